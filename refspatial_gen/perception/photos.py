"""Unlabelled photos for the image source: a folder of images -> perceived annotations -> `build_frame`.

The image source calls `photo_ids` for its unit keys and `load_photo` for a unit when its config has a
`perception:` section. One unit = one photo, id = its path under the image folder without the suffix.
`load_photo` runs the perception stages (cached; see pipeline.py) on the photo's fixed block of
`batch_size` photos in sorted order, turns the kept detections into annotations (SAM masks, or boxes
without a segmenter), resolves intrinsics (depth.py), hands the metric depth to the `perception` depth
estimator, and lets the image source lift everything as it lifts human annotations. Then captions
(captions.py) and a record of what perception did go into the frame. Drops, by reason: the image filters'
(filters.py), `image_duplicate`, `no_detections`, and the image source's own (`too_few_objects`, ...);
detections removed inside a kept photo are counted in `frame.meta["truth"]` as `perception_<reason>`.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.mask import RLE
from refspatial_gen.perception.cache import array_hash, content_hash
from refspatial_gen.perception.pipeline import Item, NeedsCompute, Perceived, Perceiver, get_perceiver

IMAGE_EXTS = (".jpg", ".jpeg", ".png", ".bmp", ".webp")
_DEPTH: dict[str, tuple[np.ndarray, str, dict]] = {}  # rgb hash -> (metric depth, origin, meta), for the estimator


def image_folder(root: str | Path, pcfg: dict[str, Any], source_images_dir: str | None) -> Path:
    root = Path(root)
    hint = pcfg.get("images_dir") or source_images_dir
    if hint:
        return root / hint
    return root / "images" if (root / "images").is_dir() else root


@lru_cache(maxsize=8)
def _listing(folder: str, stamp: float) -> tuple[tuple[str, str, int, int], ...]:
    base = Path(folder)
    if not base.is_dir():
        raise ValueError(f"photo folder {base} does not exist")
    out = []
    for p in sorted(base.rglob("*")):
        if p.suffix.lower() in IMAGE_EXTS and p.is_file() and not p.stem.lower().endswith("_depth"):
            st = p.stat()
            out.append((p.relative_to(base).with_suffix("").as_posix(), str(p), st.st_size, st.st_mtime_ns))
    return tuple(sorted(out))


def listing(root: str | Path, cfg: dict[str, Any]) -> tuple[tuple[str, str, int, int], ...]:
    """(image id, path, size, mtime) of every photo, sorted by id."""
    folder = image_folder(root, cfg["perception"], cfg.get("images_dir"))
    return _listing(str(folder.resolve()), folder.stat().st_mtime if folder.exists() else 0.0)


def photo_ids(root: str | Path, cfg: dict[str, Any]) -> list[str]:
    return [iid for iid, *_ in listing(root, cfg)]


def perceiver(cfg: dict[str, Any]) -> Perceiver:
    """The worker's Perceiver for a source config (models load once, on first use)."""
    return get_perceiver(cfg["perception"])


def _item(iid: str, path: str) -> Item:
    from refspatial_gen.sources.image.source import decode_rgb

    rgb = decode_rgb(Path(path))
    return Item(iid, content_hash(Path(path).read_bytes()), rgb)


def perceive_photo(root: str | Path, cfg: dict[str, Any], iid: str) -> tuple[Item, Perceived]:
    """The photo's perception (raises its DropUnit): from the cache when complete, else its whole block."""
    from refspatial_gen.perception.filters import duplicate_index

    P = perceiver(cfg)
    lst = listing(root, cfg)
    ids = [x[0] for x in lst]
    if iid not in ids:
        raise DropUnit("unknown_image", iid)
    k = ids.index(iid)
    fcfg = P.cfg["filters"]
    dups: dict[str, str] = {}
    if fcfg["duplicate_distance"] >= 0:
        dups = duplicate_index(lst, fcfg["duplicate_distance"], None if P.cache.root is None else str(P.cache.root))
        if iid in dups:
            raise DropUnit("image_duplicate", f"{iid} repeats {dups[iid]}")
    item = _item(iid, lst[k][1])
    try:
        res = P.run([item], may_compute=False)[0]
    except NeedsCompute:
        B = P.rt.batch_size
        block = []
        for bid, bpath, _, _ in lst[(k // B) * B : (k // B + 1) * B]:
            if bid == iid:
                block.append(item)
            elif bid not in dups:
                try:
                    block.append(_item(bid, bpath))
                except DropUnit:
                    continue  # its own unit reports it
        res = P.run(block)[[b.iid for b in block].index(iid)]
    if isinstance(res, DropUnit):
        raise res
    return item, res


def _annotations(res: Perceived, W: int, H: int, min_fill: float) -> tuple[list, dict[str, int]]:
    from refspatial_gen.sources.image.annotations import Annotation

    anns, drops = [], {}
    for k, d in enumerate(res.detections):
        if res.masks is None:
            anns.append(Annotation(f"det{k}", d.label, d.box, "box"))
            continue
        m = res.masks[k]
        box_area = max(1.0, d.area())
        if m.sum() < min_fill * box_area:
            drops["perception_mask_too_small"] = drops.get("perception_mask_too_small", 0) + 1
            continue
        ys, xs = np.nonzero(m)
        bbox = (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
        anns.append(Annotation(f"det{k}", d.label, bbox, "rle", RLE.encode(m).to_json()))
    return anns, drops


def _record(res: Perceived, P: Perceiver, drops: dict[str, int]) -> tuple[dict, dict]:
    truth = {f"perception_{k}": v for k, v in res.drops.items()}
    for k, v in drops.items():
        truth[k] = truth.get(k, 0) + v
    meta = {
        "models": P.model_meta(),
        "filter_scores": res.scores,
        "names_asked": len(res.names),
        "detections": [
            {"label": d.label, "score": round(d.score, 4), "box": [round(x, 2) for x in d.box]} for d in res.detections
        ],
    }
    return truth, meta


def load_photo(root: str | Path, iid: str, rng: np.random.Generator, cfg: dict[str, Any], build_frame: Callable) -> Any:
    """One unlabelled photo -> one Frame, through the image source's `build_frame` (or DropUnit); lifted
    objects outside their category's size range are removed there (sources/image/truthcheck.py)."""
    from refspatial_gen.perception import depth as dp
    from refspatial_gen.perception.captions import caption_frame
    from refspatial_gen.sources.image.annotations import Collection, ImageRecord

    P = perceiver(cfg)
    item, res = perceive_photo(root, cfg, iid)  # DropUnit("unknown_image") for an id not in the folder
    path = Path(dict((i, p) for i, p, _, _ in listing(root, cfg))[iid])
    H, W = item.rgb.shape[:2]
    fam = P.refs["depth"].family if "depth" in P.refs else None
    intr = dp.resolve(P.cfg["intrinsics"], path, W, H, float(cfg.get("hfov_deg") or 60.0), res.depth, fam)
    cfg2 = {**cfg, "intrinsics": "provided"}
    key = array_hash(item.rgb)
    if res.depth is not None:
        depth = dp.metric_depth(res.depth, intr, P.cfg["depth"]["max_depth"])
        how = f"perception:{fam}:metric" + (f"+focal:{intr.origin}" if res.depth.per_focal else "")
        _DEPTH[key] = (depth, how, {"model": P.model_meta()["depth"]})
        cfg2["depth"] = {"estimator": "perception"}
    anns, drops = _annotations(res, W, H, P.cfg["segmenter"]["min_box_fill"] if P.cfg.get("segmenter") else 0.0)
    try:
        rec = ImageRecord(iid, path, W, H, anns, intrinsics=(intr.fx, intr.fy, intr.cx, intr.cy))
        frame = build_frame(Collection(Path(root), "perception", {iid: rec}), rec, rng, cfg2)
    finally:
        _DEPTH.pop(key, None)
    frame.meta["intrinsics"] = intr.meta()
    truth, meta = _record(res, P, drops)
    for k, v in (frame.meta.get("truth") or {}).items():
        truth[k] = truth.get(k, 0) + v
    frame.meta["truth"] = dict(sorted(truth.items()))
    frame.meta["perception"] = meta
    caption_frame(frame, P, item.content)
    return frame


class PerceptionDepth:
    """Depth estimator `perception`: the metric depth `load_photo` computed for this very image."""

    name = "perception"
    OPTIONS: dict = {}

    def estimate(self, rgb: np.ndarray, prior):
        from refspatial_gen.depth import DepthResult

        hit = _DEPTH.get(array_hash(rgb))
        if hit is None:
            raise DropUnit("depth_missing", "the perception depth estimator serves photos loaded with perception only")
        depth, origin, meta = hit
        return DepthResult(depth.copy(), True, origin, meta)
