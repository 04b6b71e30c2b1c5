"""Export to the RefSpatial layout read by RoboRefer-style trainers (formats.md).

OUT/
  image/<name>.jpg|png      the stored RGB bytes, copied (no re-encoding); marked copies for visual choice
  depth/<name>.png          8-bit, 3-channel, per-image min-max normalised inverse depth, near = 255
  <family>.json             a JSON list of {id, image, depth, conversations[, think]}

Records group the QA pairs of one sample that share a family and image list (at most 15 per record);
reasoning pairs (those with a trace) go into their own records, which carry `think`: one entry per
pair with its question_type, trace and key steps. Roles alternate human/gpt; no <image>/<depth> tokens.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Iterable

import numpy as np

from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.marks import draw_marks, marks_of

MAX_PAIRS = 15
_EXT = {"jpeg": "jpg", "png": "png"}


def safe_name(s: str) -> str:
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


def _strip_tokens(text: str) -> str:
    return text.replace("<image>", "").replace("<depth>", "").strip()


def _write_once(path: Path, data: bytes) -> None:
    if not path.exists():
        path.write_bytes(data)


def export_sample(raw: RawSample, out: Path, with_depth: bool = True) -> dict[str, list[dict]]:
    """Write one sample's images and return its records by family."""
    h = raw.header
    base = safe_name(h["sample_id"])
    views = int(h["views"])
    frame_ids = list(h["frame_ids"])
    names: dict[int, str] = {}
    for v in range(views):
        data, fmt = raw.image_bytes(v)
        names[v] = f"{base}_v{v}"
        _write_once(out / "image" / f"{names[v]}.{_EXT.get(fmt, fmt)}", data)
        if with_depth:
            _write_once(out / "depth" / f"{names[v]}.png", inverse_depth_png(raw.depth(v)))
    ext = {v: _EXT.get(raw.image_bytes(v)[1], "jpg") for v in range(views)}
    groups: dict[tuple, list[tuple[int, dict]]] = {}
    for qi, qa in enumerate(raw.qa_json()):
        vs = tuple(frame_ids.index(f) for f in qa["frame_ids"] if f in frame_ids) or (0,)
        marks = marks_of(qa)
        key = (qa["family"], vs, bool(qa.get("trace")), qi if marks else -1)
        groups.setdefault(key, []).append((qi, qa))
    graphs = {g["frame_id"]: g for g in raw.graphs_json()}
    records: dict[str, list[dict]] = {}
    for (family, vs, reasoning, marked), items in sorted(groups.items(), key=lambda kv: kv[1][0][0]):
        images = [f"{names[v]}.{ext[v]}" for v in vs]
        depths = [f"{names[v]}.png" for v in vs]
        if marked >= 0:
            qa = items[0][1]
            by_view: dict[int, list[dict]] = {}
            for m in marks_of(qa):
                by_view.setdefault(int(m.get("view", 0)), []).append(m)
            import cv2

            for v, ms in sorted(by_view.items()):
                fm = raw.frame_meta(v)
                img = draw_marks(raw.rgb(v), fm, ms, graphs.get(fm["frame_id"]))
                mname = f"{names[v]}_marks{marked}.png"
                ok, buf = cv2.imencode(".png", np.ascontiguousarray(img[..., ::-1]))
                if not ok:
                    raise ValueError("marked image encoding failed")
                _write_once(out / "image" / mname, buf.tobytes())
                if v in vs:
                    images[vs.index(v)] = mname
        for start in range(0, len(items), MAX_PAIRS):
            chunk = items[start:start + MAX_PAIRS]
            conv = []
            for _, qa in chunk:
                conv.append({"from": "human", "value": _strip_tokens(qa["question"])})
                conv.append({"from": "gpt", "value": _strip_tokens(qa["answer"])})
            rec = {"id": f"{base}:{family}:{chunk[0][0]}", "image": images, "conversations": conv}
            if with_depth:
                rec["depth"] = depths
            if reasoning:
                rec["think"] = [{"question_type": qa["family"], "template": qa["template"], "trace": qa["trace"],
                                 "key_steps": qa.get("key_steps", []), "image_size": qa["image_size"]}
                                for _, qa in chunk]
            records.setdefault(family, []).append(rec)
    return records


def export_refspatial(raws: Iterable[RawSample], out: Path | str, *, with_depth: bool = True) -> dict:
    """Write the layout; returns {family: record count, "images": n, "qa_pairs": n}."""
    out = Path(out)
    (out / "image").mkdir(parents=True, exist_ok=True)
    if with_depth:
        (out / "depth").mkdir(parents=True, exist_ok=True)
    by_family: dict[str, list[dict]] = {}
    n_qa = 0
    for raw in raws:
        for fam, recs in export_sample(raw, out, with_depth).items():
            by_family.setdefault(fam, []).extend(recs)
            n_qa += sum(len(r["conversations"]) // 2 for r in recs)
    for fam, recs in sorted(by_family.items()):
        (out / f"{safe_name(fam)}.json").write_text(json.dumps(recs, ensure_ascii=False, indent=1, sort_keys=True))
    return {"records": {f: len(r) for f, r in sorted(by_family.items())}, "qa_pairs": n_qa,
            "images": len(list((out / "image").iterdir()))}


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
