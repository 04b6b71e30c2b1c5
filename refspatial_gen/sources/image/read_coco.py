"""Readers of COCO instances (polygons, compressed and uncompressed RLE) and COCO panoptic (PNG + segments)
annotation files; a malformed entry makes its image's record invalid (dropped when loaded), never the run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import InputError
from refspatial_gen.sources.image import checks as C
from refspatial_gen.sources.image.records import (
    Annotation,
    Collection,
    ImageRecord,
    find_images_dir,
    json_files,
    mark_invalid,
    peek_json,
)


def _first_entry(d: dict) -> Any:
    anns = d.get("annotations")
    return anns[0] if isinstance(anns, list) and anns else None


def is_panoptic(d: Any) -> bool:
    first = _first_entry(d) if isinstance(d, dict) else None
    return isinstance(first, dict) and "segments_info" in first


def is_coco(d: Any) -> bool:
    """A COCO instances file (its lists are checked by the reader, which names what is wrong)."""
    return isinstance(d, dict) and "images" in d and "annotations" in d and not is_panoptic(d)


def _image_records(entries: list, img_dir: Path, where: str) -> dict[str, ImageRecord]:
    """COCO `images` entries -> records; a malformed entry yields an invalid record (dropped when loaded)."""
    images: dict[str, ImageRecord] = {}
    for k, im in enumerate(entries):
        iid = C.entry_id(im.get("id")) if isinstance(im, dict) else None
        if iid is None:
            mark_invalid(
                images, f"#images[{k}]", img_dir, C.Bad("annotation_invalid", f"{where} images[{k}] has no usable id")
            )
            continue
        if iid in images:
            mark_invalid(images, iid, img_dir, C.Bad("annotation_invalid", f"{where}: image id {iid} listed twice"))
            continue
        try:
            file = C.relative_file(im.get("file_name"), img_dir, f"image {iid} file_name")
            w, h = (
                C.positive_int(im.get("width"), f"image {iid} width"),
                C.positive_int(im.get("height"), f"image {iid} height"),
            )
        except C.Bad as bad:
            mark_invalid(images, iid, img_dir, bad)
            continue
        images[iid] = ImageRecord(
            iid, file, w, h, [], meta={"file_name": im["file_name"], "license": im.get("license")}
        )
    return images


def _categories(entries: list) -> dict[int, tuple[str, bool]]:
    """id -> (name, isthing); malformed entries are left out (annotations naming them become invalid)."""
    out: dict[int, tuple[str, bool]] = {}
    for c in entries:
        if (
            isinstance(c, dict)
            and isinstance(c.get("id"), int)
            and not isinstance(c.get("id"), bool)
            and isinstance(c.get("name"), str)
        ):
            out[c["id"]] = (c["name"], bool(c.get("isthing", 1)))
    return out


def _category(cats: dict[int, tuple[str, bool]], v: Any, what: str) -> tuple[int, str, bool]:
    cid = C.int_id(v, f"{what} category_id")
    if cid not in cats:
        raise C.Bad("annotation_invalid", f"{what} category_id {cid} is not in the categories")
    return cid, *cats[cid]


def _coco_annotation(a: dict, cats: dict, what: str) -> tuple[int, Annotation]:
    aid = C.int_id(a.get("id"), f"{what} id")
    kind, payload = C.segmentation(a.get("segmentation"))
    _, name, isthing = _category(cats, a.get("category_id"), what)
    return aid, Annotation(
        str(aid),
        name,
        C.bbox_xywh(a.get("bbox"), f"{what} bbox"),
        kind,
        payload,
        C.flag(a.get("iscrowd"), f"{what} iscrowd"),
        isthing,
    )


def _attach(images: dict[str, ImageRecord], entries: list, img_dir: Path, where: str, parse) -> None:
    """Annotations -> their images, sorted by annotation id; `parse(entry, what)` -> (sort key, [Annotation])."""
    per_image: dict[str, list] = {}
    for k, a in enumerate(entries):
        iid = C.entry_id(a.get("image_id")) if isinstance(a, dict) else None
        if iid is None:
            mark_invalid(
                images,
                f"#annotations[{k}]",
                img_dir,
                C.Bad("annotation_invalid", f"{where} annotations[{k}] has no usable image_id"),
            )
            continue
        rec = images.get(iid)
        if rec is None or rec.meta.get("invalid"):
            continue  # an image this file does not list (a subset), or one already dropped
        try:
            key, anns = parse(a, f"image {iid} annotation {a.get('id', k)}")
        except C.Bad as bad:
            mark_invalid(images, iid, img_dir, bad)
            continue
        per_image.setdefault(iid, []).append((key, anns))
    for iid, items in per_image.items():
        if not images[iid].meta.get("invalid"):
            for _, anns in sorted(items, key=lambda t: t[0]):
                images[iid].annotations.extend(anns)


def _top_level(root: Path, annotations: str | None, pick, what: str) -> tuple[Path, dict]:
    """The annotation file (named, or the first in `root` that `pick` accepts) and its data, checked."""
    if annotations:
        ann_file = root / annotations
        data = C.load_json_file(ann_file)
    else:
        cands = [p for p in json_files(root) if pick(peek_json(p))]
        if not cands:
            raise InputError(str(root), f"no {what} JSON found")
        ann_file = cands[0]
        data = C.load_json_file(ann_file)
    if not isinstance(data, dict):
        raise InputError(str(ann_file), f"a {what} file must be a JSON object, got {type(data).__name__}")
    return ann_file, data


def read_coco(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    ann_file, data = _top_level(root, annotations, is_coco, "COCO instances")
    entries = C.require_list(data, "images", ann_file)
    anns = C.require_list(data, "annotations", ann_file)
    cats = _categories(C.require_list(data, "categories", ann_file))
    img_dir = find_images_dir(root, images_dir)
    images = _image_records(entries, img_dir, ann_file.name)

    def parse(a: dict, what: str):
        aid, ann = _coco_annotation(a, cats, what)
        return aid, [ann]

    _attach(images, anns, img_dir, ann_file.name, parse)
    return Collection(root, "coco", images)


def read_coco_panoptic(root: Path, annotations: str | None = None, images_dir: str | None = None) -> Collection:
    ann_file, data = _top_level(root, annotations, is_panoptic, "COCO panoptic")
    cat_list = C.require_list(data, "categories", ann_file, required=False)
    if not cat_list and (root / "panoptic_coco_categories.json").is_file():
        cat_list = C.load_json_file(root / "panoptic_coco_categories.json")
        if not isinstance(cat_list, list):
            raise InputError(str(root / "panoptic_coco_categories.json"), "must be a JSON list of categories")
    cats = _categories(cat_list)
    img_dir = find_images_dir(root, images_dir)
    png_dirs = [
        d
        for d in sorted(root.iterdir())
        if d.is_dir() and d != img_dir and any(p.suffix == ".png" for p in d.iterdir())
    ]
    images = _image_records(C.require_list(data, "images", ann_file), img_dir, ann_file.name)
    pngs: dict[str, Path | None] = {}

    def parse(a: dict, what: str):
        iid = str(C.entry_id(a["image_id"]))
        C.relative_file(a.get("file_name"), root, f"{what} file_name")  # a plain relative name, or the image drops
        names = [C.relative_file(a.get("file_name"), d, f"{what} file_name") for d in png_dirs]
        pngs[iid] = next((p for p in names if p.is_file()), None)
        segs = a.get("segments_info")
        if not isinstance(segs, list):
            raise C.Bad("annotation_invalid", f"{what} segments_info must be a list")
        out = []
        for j, sg in enumerate(segs):
            if not isinstance(sg, dict):
                raise C.Bad("annotation_invalid", f"{what} segments_info[{j}] must be a mapping")
            sid = C.int_id(sg.get("id"), f"{what} segment id")
            _, name, isthing = _category(cats, sg.get("category_id"), f"{what} segment {sid}")
            out.append(
                (
                    sid,
                    Annotation(
                        str(sid),
                        name,
                        C.bbox_xywh(sg.get("bbox"), f"{what} segment {sid} bbox"),
                        "panoptic",
                        sid,
                        C.flag(sg.get("iscrowd"), f"{what} iscrowd"),
                        isthing,
                    ),
                )
            )
        return iid, [ann for _, ann in sorted(out, key=lambda t: t[0])]

    _attach(images, C.require_list(data, "annotations", ann_file), img_dir, ann_file.name, parse)
    for iid, png in pngs.items():
        images[iid].panoptic_png = png
    return Collection(root, "coco_panoptic", images)
