"""A contact sheet of generated scenes (first view of each), to look at what the simulator makes, with
the scene statistics a reviewer asks for: objects per scene and support surfaces per room."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit


def scene_stats(frames, desc) -> dict[str, Any]:
    """Objects placed / visible in the first view, and furniture surfaces (not the floor) holding objects."""
    from refspatial_gen.sources.sim.source import _root_support

    roots = [_root_support(desc, o) for o in desc.objects]
    furniture = {s.id for s in desc.surfaces if s.kind != "floor"}
    visible = {o.id - 1 for o in frames[0].objects}
    return {
        "layout": desc.kind,
        "placed": len(desc.objects),
        "visible": len(visible),
        "surfaces": len({r for r in roots if r in furniture}),
        "surfaces_visible": len({roots[k] for k in visible if roots[k] in furniture}),
    }


def _summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for kind in ("all", "room", "tabletop"):
        rs = [r for r in rows if kind == "all" or r["layout"] == kind]
        if rs:
            out[kind] = {
                "scenes": len(rs),
                **{
                    f"median_{k}": float(np.median([r[k] for r in rs]))
                    for k in ("placed", "visible", "surfaces", "surfaces_visible")
                },
                "min_surfaces": min(r["surfaces"] for r in rs),
            }
    return out


def gallery(
    out: str | Path,
    n_scenes: int = 24,
    seed: int = 0,
    config: dict[str, Any] | None = None,
    cols: int = 6,
    thumb_width: int = 320,
    quality: int = 85,
    rng_for: Callable[[str], np.random.Generator] | None = None,
) -> dict[str, Any]:
    """Render `n_scenes` scenes (the config's layout mix; tabletop and room alternately if it has none).
    `rng_for(unit key)`: the run's unit generators; with it the sheet shows exactly the scenes a run makes
    (the run's config, no forced layouts)."""
    from PIL import Image, ImageDraw

    from refspatial_gen.sources.sim import generate

    config = dict(config or {})
    thumbs, drops, rows = [], {}, []
    i = 0
    while len(thumbs) < n_scenes and i < 3 * n_scenes:
        cfg = dict(config)
        if "layouts" not in config and rng_for is None:
            cfg["layouts"] = {"room": 1.0} if i % 2 else {"tabletop": 1.0}
        key = f"sim:{i:06d}"
        try:
            frames, desc, _ = generate(
                key, rng_for(key) if rng_for else np.random.default_rng([seed, i]), cfg, keep_scene=True
            )
        except DropUnit as e:
            drops[e.reason] = drops.get(e.reason, 0) + 1
            i += 1
            continue
        rows.append(scene_stats(frames, desc))
        f = frames[0]
        im = Image.fromarray(f.rgb)
        h = round(im.height * thumb_width / im.width)
        im = im.resize((thumb_width, h), Image.LANCZOS)
        d = ImageDraw.Draw(im)
        d.rectangle([0, 0, thumb_width, 14], fill=(0, 0, 0))
        d.text(
            (3, 1),
            f"{key} {f.meta['layout']} {len(f.objects)}/{len(desc.objects)} obj {rows[-1]['surfaces']} surf",
            fill=(255, 255, 255),
        )
        thumbs.append(im)
        i += 1
    if not thumbs:
        raise DropUnit("gallery_empty", f"every scene was dropped: {drops}")
    nrows = (len(thumbs) + cols - 1) // cols
    w, h = thumbs[0].size
    sheet = Image.new("RGB", (cols * w, nrows * h), (255, 255, 255))
    for k, t in enumerate(thumbs):
        sheet.paste(t, ((k % cols) * w, (k // cols) * h))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() in (".jpg", ".jpeg"):
        sheet.save(out, quality=quality, optimize=True)
    else:
        sheet.save(out)
    return {
        "out": str(out),
        "scenes": len(thumbs),
        "dropped": drops,
        "bytes": out.stat().st_size,
        "stats": _summary(rows),
    }
