"""Image filters, cheap ones always and an optional CLIP/SigLIP one, each drop counted by its reason.

RefSpatial keeps 466k of 1.7M OpenImages photos; what survives must show a scene with objects that can
be measured. Cheap checks first (they cost milliseconds): `image_too_small` (shorter side), `image_aspect`
(panoramas, strips), `image_too_dark`, `image_washed_out` (mean grey level), `image_clipped` (share of
pixels at 0 or 255: over- or under-exposed), `image_blurry` (variance of the Laplacian of the grey image
scaled to 512 px on its long side, so the score does not depend on resolution), `image_duplicate` (the
64-bit difference hash is within `duplicate_distance` bits of an image earlier in the sorted
collection: the first copy is kept, whichever worker reads it). Then, optionally, `image_rejected_by_clip`:
the best positive prompt's probability minus the best negative's must exceed `min_margin`.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit


def grey(rgb: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY)


def blur_score(g: np.ndarray) -> float:
    """Variance of the Laplacian at 512 px on the long side (INTER_AREA when shrinking)."""
    import cv2

    s = 512.0 / max(g.shape)
    if s < 1.0:
        g = cv2.resize(g, (max(1, round(g.shape[1] * s)), max(1, round(g.shape[0] * s))), interpolation=cv2.INTER_AREA)
    return float(cv2.Laplacian(g, cv2.CV_64F).var())


def cheap_checks(rgb: np.ndarray, f: dict[str, Any]) -> dict[str, float]:
    """Scores of the cheap filters; raises DropUnit with the first failing reason."""
    H, W = rgb.shape[:2]
    if min(H, W) < f["min_side"]:
        raise DropUnit("image_too_small", f"{W}x{H}: shorter side < {f['min_side']}")
    if max(H, W) / max(1, min(H, W)) > f["max_aspect"]:
        raise DropUnit("image_aspect", f"{W}x{H}: aspect ratio > {f['max_aspect']}")
    g = grey(rgb)
    mean = float(g.mean())
    clipped = float(((g <= 2) | (g >= 253)).mean())
    blur = blur_score(g)
    scores = {"brightness": round(mean, 3), "clipped": round(clipped, 5), "blur": round(blur, 3)}
    if mean < f["min_brightness"]:
        raise DropUnit("image_too_dark", f"mean grey {mean:.1f} < {f['min_brightness']}")
    if mean > f["max_brightness"]:
        raise DropUnit("image_washed_out", f"mean grey {mean:.1f} > {f['max_brightness']}")
    if clipped > f["max_clipped"]:
        raise DropUnit("image_clipped", f"{clipped:.2f} of pixels at 0 or 255 > {f['max_clipped']}")
    if blur < f["blur_threshold"]:
        raise DropUnit("image_blurry", f"variance of Laplacian {blur:.1f} < {f['blur_threshold']}")
    return scores


def dhash(path: Path) -> int:
    """64-bit difference hash of the grey image (9x8, horizontal gradient signs)."""
    from PIL import Image

    with Image.open(path) as im:
        im.draft("L", (64, 64))
        g = np.asarray(im.convert("L").resize((9, 8), Image.BILINEAR), np.int16)
    bits = (g[:, 1:] > g[:, :-1]).reshape(-1)
    return int(sum(1 << i for i, b in enumerate(bits) if b))


def duplicates(hashes: list[tuple[str, int | None]], distance: int) -> dict[str, str]:
    """image id -> id of the first earlier image within `distance` bits (multi-index hashing: two hashes
    within d bits share one of d+1 equal 64/(d+1)-bit blocks, so only those pairs are compared)."""
    blocks = distance + 1
    width = 64 // blocks
    masks = [((1 << width) - 1) << (k * width) for k in range(blocks)]
    masks[-1] = ((1 << 64) - 1) ^ sum(masks[:-1])
    index: dict[tuple[int, int], list[tuple[str, int]]] = {}
    out: dict[str, str] = {}
    for iid, h in hashes:
        if h is None:
            continue
        cands = {c for k, m in enumerate(masks) for c in index.get((k, h & m), [])}
        best = sorted(c for c in cands if bin(c[1] ^ h).count("1") <= distance)
        if best:
            out[iid] = best[0][0]
            continue  # a duplicate is not indexed: the first copy stands for its group
        for k, m in enumerate(masks):
            index.setdefault((k, h & m), []).append((iid, h))
    return out


@lru_cache(maxsize=4)
def duplicate_index(
    listing: tuple[tuple[str, str, int, int], ...], distance: int, cache_dir: str | None
) -> dict[str, str]:
    """Duplicates over a collection listing ((id, path, size, mtime_ns) sorted by id), computed once per
    process and kept on disk next to the model cache (keyed by the listing)."""
    from refspatial_gen.perception.cache import key_of

    key = key_of("dhash-v1", [(i, s, m) for i, _, s, m in listing], distance)
    path = Path(cache_dir) / "duplicates" / f"{key}.json" if cache_dir else None
    if path is not None and path.is_file():
        return json.loads(path.read_text(encoding="utf-8"))
    hashes = []
    for iid, p, _, _ in listing:
        try:
            hashes.append((iid, dhash(Path(p))))
        except (OSError, ValueError, SyntaxError):  # undecodable: its own unit drops it
            hashes.append((iid, None))
    out = duplicates(hashes, distance)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(out, sort_keys=True), encoding="utf-8")
        tmp.replace(path)
    return out


def clip_check(scorer, rgb: np.ndarray, clip_cfg: dict[str, Any]) -> dict[str, float]:
    """The optional CLIP/SigLIP filter: raises DropUnit('image_rejected_by_clip') below the margin."""
    pos, neg = [str(x) for x in clip_cfg["positive"]], [str(x) for x in clip_cfg["negative"]]
    p = scorer.scores([rgb], pos + neg)[0]
    margin = float(p[: len(pos)].max() - p[len(pos) :].max())
    if margin <= clip_cfg["min_margin"]:
        best = neg[int(np.argmax(p[len(pos) :]))]
        raise DropUnit(
            "image_rejected_by_clip", f"margin {margin:.3f} <= {clip_cfg['min_margin']} (best negative: {best!r})"
        )
    return {"clip_margin": round(margin, 4)}
