"""Export to the RefSpatial layout read by RoboRefer-style trainers (formats.md).

OUT/
  image/<stem>_v<k>.jpg|png  the stored RGB bytes of view k, copied (no re-encoding);
                             image/<stem>_v<k>_marks<q>.png: marked copies for visual choice
  depth/<stem>_v<k>.png      8-bit, 3-channel, per-image min-max normalised inverse depth, near = 255
  <family>.json              a JSON list of {id, image, depth, conversations[, think]}
(<stem>: the sample id, or its safe characters plus a hash when it has others: export_files.sample_stem)

Records group the QA pairs of one sample that share a family and image list (at most 15 per record);
reasoning pairs (those with a trace) go into their own records, which carry `think`: one entry per
pair with its question_type, trace and key steps. Roles alternate human/gpt; no <image>/<depth> tokens.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from refspatial_gen.shards.export_files import (
    EXT,
    StemRegistry,
    check_image_refs,
    file_sha256,
    sha256,
    stored_image_hashes,
    view_name,
    write_new,
)
from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.marks import marked_pngs, marks_of
from refspatial_gen.shards.records import strip_tokens

MAX_PAIRS = 15
_EXT = EXT  # older name, imported by other exporters


def safe_name(s: str) -> str:
    """A family name as a file name (family names are plain words; this only guards odd ones)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", s).strip("_") or "x"


def inverse_depth_png(depth: np.ndarray) -> bytes:
    """Metric depth (0 = unknown) -> 8-bit 3-channel PNG of min-max normalised inverse depth (near = 255)."""
    import cv2

    d = np.asarray(depth, np.float64)
    valid = np.isfinite(d) & (d > 0)
    out = np.zeros(d.shape, np.uint8)
    if valid.any():
        inv = np.zeros_like(d)
        inv[valid] = 1.0 / d[valid]
        lo, hi = inv[valid].min(), inv[valid].max()
        scaled = (inv - lo) / (hi - lo) if hi > lo else np.ones_like(inv)
        out[valid] = np.clip(np.round(scaled[valid] * 255.0), 0, 255).astype(np.uint8)  # unknown stays 0 (= far)
    ok, buf = cv2.imencode(".png", np.repeat(out[..., None], 3, axis=2), [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise ValueError("depth PNG encoding failed")
    return buf.tobytes()


def export_sample(
    raw: RawSample, out: Path, with_depth: bool = True, stems: StemRegistry | None = None
) -> dict[str, list[dict]]:
    """Write one sample's images (each file created once: a collision raises) and return its records by family."""
    h = raw.header
    base = (stems or StemRegistry()).claim(h["sample_id"])
    views = int(h["views"])
    frame_ids = list(h["frame_ids"])
    images: dict[int, str] = {}
    for v in range(views):
        data, fmt = raw.image_bytes(v)
        images[v] = view_name(base, v, EXT.get(fmt, fmt))
        write_new(out / "image" / images[v], data)
        if with_depth:
            write_new(out / "depth" / view_name(base, v, "png"), inverse_depth_png(raw.depth(v)))
    groups: dict[tuple, list[tuple[int, dict]]] = {}
    for qi, qa in enumerate(raw.qa_json()):
        vs = tuple(frame_ids.index(f) for f in qa["frame_ids"] if f in frame_ids) or (0,)
        key = (qa["family"], vs, bool(qa.get("trace")), qi if marks_of(qa) else -1)
        groups.setdefault(key, []).append((qi, qa))
    records: dict[str, list[dict]] = {}
    for (family, vs, reasoning, marked), items in sorted(groups.items(), key=lambda kv: kv[1][0][0]):
        names = [images[v] for v in vs]
        if marked >= 0:
            for v, png in marked_pngs(raw, items[0][1]).items():
                mname = marked_name(base, v, marked)
                write_new(out / "image" / mname, png)
                if v in vs:
                    names[vs.index(v)] = mname
        for start in range(0, len(items), MAX_PAIRS):
            records.setdefault(family, []).append(
                _record(
                    f"{base}:{family}:{items[start][0]}",
                    names,
                    [view_name(base, v, "png") for v in vs],
                    items[start : start + MAX_PAIRS],
                    with_depth,
                    reasoning,
                )
            )
    return records


def marked_name(stem: str, view: int, qa_index: int) -> str:
    """The marked copy of a view for the QA pair at `qa_index` of its sample."""
    return f"{stem}_v{view}_marks{qa_index}.png"


def _record(
    rid: str, images: list[str], depths: list[str], chunk: list[tuple[int, dict]], with_depth: bool, reasoning: bool
) -> dict:
    conv = []
    for _, qa in chunk:
        conv.append({"from": "human", "value": strip_tokens(qa["question"])})
        conv.append({"from": "gpt", "value": strip_tokens(qa["answer"])})
    rec = {"id": rid, "image": images, "conversations": conv}
    if with_depth:
        rec["depth"] = depths
    if reasoning:
        rec["think"] = [
            {
                "question_type": qa["family"],
                "template": qa["template"],
                "trace": qa["trace"],
                "key_steps": qa.get("key_steps", []),
                "image_size": qa["image_size"],
            }
            for _, qa in chunk
        ]
    return rec


def export_refspatial(raws: Iterable[RawSample], out: Path | str, *, with_depth: bool = True) -> dict:
    """Write the layout into `out` (a fresh folder: see shards.export); returns record counts by family."""
    out = Path(out)
    (out / "image").mkdir(parents=True, exist_ok=True)
    if with_depth:
        (out / "depth").mkdir(parents=True, exist_ok=True)
    by_family: dict[str, list[dict]] = {}
    n_qa = 0
    stems = StemRegistry()
    for raw in raws:
        for fam, recs in export_sample(raw, out, with_depth, stems).items():
            by_family.setdefault(fam, []).extend(recs)
            n_qa += sum(len(r["conversations"]) // 2 for r in recs)
    for fam, recs in sorted(by_family.items()):
        write_new(
            out / f"{safe_name(fam)}.json", json.dumps(recs, ensure_ascii=False, indent=1, sort_keys=True).encode()
        )
    return {
        "records": {f: len(r) for f, r in sorted(by_family.items())},
        "qa_pairs": n_qa,
        "images": len(list((out / "image").iterdir())),
    }


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """RoboRefer's loader rules, plus: every image a record names holds the bytes the shards store for
    that sample and view, and every depth map is the one computed from that view's stored depth."""
    out = Path(out)
    errors = check_roborefer_layout(out)
    depth_want: dict[str, str] = {}

    def depth_hash(raw: RawSample, stem: str, v: int) -> None:
        if (out / "depth").is_dir():
            depth_want[view_name(stem, v, "png")] = sha256(inverse_depth_png(raw.depth(v)))

    stored = stored_image_hashes(raws, depth_hash)
    refs, deps = [], []
    for f in sorted(out.glob("*.json")):
        try:
            recs = json.loads(f.read_text())
        except ValueError:
            continue  # reported by check_roborefer_layout
        for rec in recs if isinstance(recs, list) else []:
            refs += list(rec.get("image") or [])
            deps += list(rec.get("depth") or [])
    errors += check_image_refs(out / "image", refs, stored, str(out))
    for d in sorted(set(deps)):
        got = file_sha256(out / "depth" / d)
        if depth_want.get(d) is None or got != depth_want[d]:
            errors.append(f"{out}: depth map {d} is not the one computed from the stored depth of its view")
    return errors


def check_roborefer_layout(out: Path | str) -> list[str]:
    """RoboRefer's loader rules, checked on an export; returns the violations (empty = passes).

    One JSON list per file; records have image, depth, conversations; roles alternate human/gpt from
    human; no <image>/<depth> tokens; depth PNGs 8-bit 3-channel the size of their RGB; <= 15 pairs.
    """
    import cv2

    out = Path(out)
    errors: list[str] = []
    files = sorted(out.glob("*.json"))
    if not files:
        return [f"{out}: no JSON files"]
    sizes: dict[str, tuple[int, int]] = {}
    for f in files:
        try:
            data = json.loads(f.read_text())
        except json.JSONDecodeError as e:
            errors.append(f"{f.name}: not JSON ({e})")
            continue
        if not isinstance(data, list):
            errors.append(f"{f.name}: top level is {type(data).__name__}, not a list")
            continue
        for rec in data:
            rid = f"{f.name}:{rec.get('id')}"
            for k in ("id", "image", "depth", "conversations"):
                if k not in rec:
                    errors.append(f"{rid}: missing {k!r}")
            conv = rec.get("conversations") or []
            if not conv or len(conv) % 2:
                errors.append(f"{rid}: {len(conv)} turns (need a positive even number)")
            for i, turn in enumerate(conv):
                want = "human" if i % 2 == 0 else "gpt"
                if turn.get("from") != want:
                    errors.append(f"{rid}: turn {i} is from {turn.get('from')!r}, expected {want!r}")
                v = turn.get("value")
                if not isinstance(v, str) or not v.strip():
                    errors.append(f"{rid}: turn {i} has empty value")
                elif "<image>" in v or "<depth>" in v:
                    errors.append(f"{rid}: turn {i} contains an <image>/<depth> token")
            if len(conv) // 2 > MAX_PAIRS:
                errors.append(f"{rid}: {len(conv) // 2} QA pairs > {MAX_PAIRS}")
            if "think" in rec and len(rec["think"]) != len(conv) // 2:
                errors.append(f"{rid}: {len(rec['think'])} think entries for {len(conv) // 2} QA pairs")
            imgs, deps = rec.get("image") or [], rec.get("depth") or []
            if len(imgs) != len(deps):
                errors.append(f"{rid}: {len(imgs)} images but {len(deps)} depth maps")
            for im, dp in zip(imgs, deps):
                if im not in sizes:
                    a = cv2.imread(str(out / "image" / im), cv2.IMREAD_UNCHANGED)
                    sizes[im] = None if a is None else a.shape[:2]
                if sizes[im] is None:
                    errors.append(f"{rid}: image {im} missing or unreadable")
                    continue
                key = "depth:" + dp
                if key not in sizes:
                    b = cv2.imread(str(out / "depth" / dp), cv2.IMREAD_UNCHANGED)
                    if b is None:
                        sizes[key] = None
                    else:
                        sizes[key] = b.shape[:2]
                        if b.dtype != np.uint8 or b.ndim != 3 or b.shape[2] != 3:
                            errors.append(f"{rid}: depth {dp} is {b.dtype} with shape {b.shape}, need 8-bit 3-channel")
                if sizes[key] is None:
                    errors.append(f"{rid}: depth {dp} missing or unreadable")
                elif sizes[key] != sizes[im]:
                    errors.append(f"{rid}: depth {dp} is {sizes[key]}, its image is {sizes[im]}")
    return errors
