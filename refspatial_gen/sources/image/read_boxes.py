"""Readers of box collections: OpenImages (box CSV, optional mask CSV + mask PNGs) and SUN RGB-D 2D boxes
(folders with image.jpg, depth.png, annotation.json; only the 2D boxes and K are read, never the 3D ground
truth)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from refspatial_gen.core.errors import InputError
from refspatial_gen.sources.image import checks as C
from refspatial_gen.sources.image.records import (
    IMAGE_EXTS,
    Annotation,
    Collection,
    ImageRecord,
    csv_head,
    find_images_dir,
    mark_invalid,
    peek_json,
)


def _read_csv(path: Path, required: tuple[str, ...] = ()) -> list[dict[str, str]]:
    try:
        with open(path, encoding="utf-8", newline="") as f:
            reader = csv.DictReader(f)
            missing = [c for c in required if c not in (reader.fieldnames or [])]
            if missing:
                raise InputError(str(path), f"missing column(s) {', '.join(missing)}")
            return list(reader)
    except (UnicodeDecodeError, csv.Error) as e:
        raise InputError(str(path), f"not a readable CSV file ({type(e).__name__})") from None


BOX_COLUMNS = ("ImageID", "LabelName", "XMin", "XMax", "YMin", "YMax")


MASK_COLUMNS = ("MaskPath", "ImageID", "LabelName", "BoxXMin", "BoxYMin", "BoxXMax", "BoxYMax")


def _num(row: dict[str, str], col: str, what: str) -> float:
    try:
        return C.finite(float(row.get(col) or "nan"), f"{what} {col}")
    except ValueError:
        raise C.Bad("annotation_invalid", f"{what} {col} is not a number: {str(row.get(col))[:30]!r}") from None


def read_openimages(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    """OpenImages V4+ CSVs: boxes (ImageID, LabelName, XMin, XMax, YMin, YMax, Is*), optional masks
    (MaskPath, ImageID, LabelName, BoxXMin...) with PNGs under `masks/`, and class descriptions
    (LabelName,DisplayName; with or without a header). Coordinates are normalised to [0, 1]."""
    names: dict[str, str] = {}
    box_rows: list[dict[str, str]] = []
    mask_rows: list[dict[str, str]] = []
    for p in sorted(root.glob("*.csv")):
        head = csv_head(p)
        if "MaskPath" in head:
            mask_rows.extend(_read_csv(p, MASK_COLUMNS))
        elif "XMin" in head:
            box_rows.extend(_read_csv(p, BOX_COLUMNS))
        else:
            try:
                with open(p, encoding="utf-8", newline="") as f:
                    for row in csv.reader(f):
                        if len(row) >= 2 and row[0] != "LabelName":
                            names[row[0]] = row[1]
            except (UnicodeDecodeError, csv.Error) as e:
                raise InputError(str(p), f"not a readable CSV file ({type(e).__name__})") from None
    if annotations:
        box_rows = _read_csv(root / annotations, BOX_COLUMNS)
    img_dir = find_images_dir(root, images_dir)
    mask_dir = root / "masks"
    files = {p.stem: p for p in sorted(img_dir.iterdir()) if p.suffix.lower() in IMAGE_EXTS} if img_dir.is_dir() else {}
    images: dict[str, ImageRecord] = {}

    def rec_for(iid: str) -> ImageRecord:
        if iid not in images:
            images[iid] = ImageRecord(iid, files.get(iid, img_dir / f"{iid}.jpg"), None, None, [])
        return images[iid]

    rows = mask_rows if mask_rows else box_rows
    order = (
        (lambda r: (r["ImageID"], r["MaskPath"]))
        if mask_rows
        else (lambda r: (r["ImageID"], r["LabelName"], r["XMin"], r["YMin"]))
    )
    for k, r in enumerate(sorted(rows, key=lambda r: tuple(str(x) for x in order(r)))):
        iid = C.entry_id(r["ImageID"])
        if iid is None:
            mark_invalid(images, f"#rows[{k}]", img_dir, C.Bad("annotation_invalid", f"CSV row {k} has no ImageID"))
            continue
        label = r["LabelName"]
        try:
            if mask_rows:
                bb = tuple(_num(r, c, f"image {iid}") for c in ("BoxXMin", "BoxYMin", "BoxXMax", "BoxYMax"))
                ann = Annotation(
                    f"m{k}",
                    names.get(label, label),
                    bb,
                    "mask_png",
                    C.relative_file(r["MaskPath"], mask_dir, f"image {iid} MaskPath"),
                    attributes={},
                )
            else:
                bb = (
                    _num(r, "XMin", f"image {iid}"),
                    _num(r, "YMin", f"image {iid}"),
                    _num(r, "XMax", f"image {iid}"),
                    _num(r, "YMax", f"image {iid}"),
                )
                ann = Annotation(
                    f"b{k}",
                    names.get(label, label),
                    bb,
                    "box",
                    None,
                    iscrowd=r.get("IsGroupOf", "0") == "1",
                    attributes={},
                )
        except C.Bad as bad:
            rec_for(iid).meta.setdefault("invalid", (bad.reason, bad.detail))
            continue
        rec_for(iid).annotations.append(ann)
    for rec in images.values():
        rec.meta["normalised_boxes"] = True
    return Collection(root, "openimages", images)


def _sunrgbd_record(d: Path) -> ImageRecord:
    """One SUN RGB-D folder -> its record; any malformed value makes the record invalid (dropped on load)."""
    rec = ImageRecord(d.name, d / "image.jpg", None, None, [])
    try:
        a = peek_json(d / "annotation.json")
        if not isinstance(a, dict):
            raise C.Bad("annotation_invalid", f"{d.name}/annotation.json is not a readable JSON object")
        K = np.asarray(a.get("K"), dtype=object)
        if K.shape != (3, 3):
            raise C.Bad("annotation_invalid", f"{d.name}: K must be a 3x3 matrix")
        K = np.array([[C.finite(v, f"{d.name} K") for v in row] for row in K.tolist()])
        scale = C.finite(a.get("depth_scale", 1000.0), f"{d.name} depth_scale")
        if scale <= 0:
            raise C.Bad("annotation_invalid", f"{d.name}: depth_scale must be > 0")
        objects = a.get("objects")
        if not isinstance(objects, list):
            raise C.Bad("annotation_invalid", f"{d.name}: objects must be a list")
        rec = ImageRecord(
            d.name,
            C.relative_file(a.get("image", "image.jpg"), d, f"{d.name} image"),
            C.positive_int(a.get("width"), f"{d.name} width"),
            C.positive_int(a.get("height"), f"{d.name} height"),
            [],
            depth_file=C.relative_file(a.get("depth", "depth.png"), d, f"{d.name} depth"),
            # the annotation's K is in 0-based pixel centres: +0.5 to the pixel-edge convention
            intrinsics=(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]) + 0.5, float(K[1, 2]) + 0.5),
            meta={"depth_scale": scale},
        )
        for k, o in enumerate(objects):
            b = o.get("bbox2d_xyxy") if isinstance(o, dict) else None
            if not isinstance(b, list) or len(b) != 4:
                raise C.Bad("annotation_invalid", f"{d.name}: object {k} bbox2d_xyxy must be [x0, y0, x1, y1]")
            x0, y0, x1, y1 = (C.finite(v, f"{d.name} object {k} bbox2d_xyxy") for v in b)
            if not isinstance(o.get("category"), str):
                raise C.Bad("annotation_invalid", f"{d.name}: object {k} category must be a string")
            # 1-based pixel centres -> continuous 0-based coordinates: first pixel x0 spans [x0-1, x0)
            rec.annotations.append(Annotation(str(k), o["category"], (x0 - 1.0, y0 - 1.0, x1, y1), "box"))
    except C.Bad as bad:
        rec.annotations = []
        rec.meta["invalid"] = (bad.reason, bad.detail)
    return rec


def read_sunrgbd(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    """SUN RGB-D folders as plain images: 2D boxes (1-based MATLAB -> 0-based), K and the depth path.
    The 3D boxes and Rtilt are deliberately not read (they are the ground truth of the evaluation)."""
    images: dict[str, ImageRecord] = {}
    for d in sorted(p for p in root.iterdir() if p.is_dir() and (p / "annotation.json").is_file()):
        images[d.name] = _sunrgbd_record(d)
    return Collection(root, "sunrgbd", images)
