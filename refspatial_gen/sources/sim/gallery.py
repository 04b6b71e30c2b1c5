"""A contact sheet of generated scenes (first view of each), to look at what the simulator makes."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit


def gallery(out: str | Path, n_scenes: int = 24, seed: int = 0, config: dict[str, Any] | None = None,
            cols: int = 6, thumb_width: int = 320, quality: int = 85,
            rng_for: Callable[[str], np.random.Generator] | None = None) -> dict[str, Any]:
    """Render `n_scenes` scenes (tabletop and room alternately unless `config` fixes the layout) into one image.
    `rng_for(unit key)`: the run's unit generators; with it the sheet shows exactly the scenes a run makes
    (the run's config, no forced layouts)."""
    from PIL import Image, ImageDraw

    from refspatial_gen.sources.sim import generate

    config = dict(config or {})
    thumbs, drops = [], {}
    i = 0
    while len(thumbs) < n_scenes and i < 3 * n_scenes:
        cfg = dict(config)
        if "layouts" not in config and rng_for is None:
            cfg["layouts"] = {"room": 1.0} if i % 3 == 2 else {"tabletop": 1.0}
        key = f"sim:{i:06d}"
        try:
            frames = generate(key, rng_for(key) if rng_for else np.random.default_rng([seed, i]), cfg)
        except DropUnit as e:
            drops[e.reason] = drops.get(e.reason, 0) + 1
            i += 1
            continue
        f = frames[0]
        im = Image.fromarray(f.rgb)
        h = round(im.height * thumb_width / im.width)
        im = im.resize((thumb_width, h), Image.LANCZOS)
        d = ImageDraw.Draw(im)
        d.rectangle([0, 0, thumb_width, 14], fill=(0, 0, 0))
        d.text((3, 1), f"{key} {f.meta['layout']} {len(f.objects)} obj", fill=(255, 255, 255))
        thumbs.append(im)
        i += 1
    if not thumbs:
        raise DropUnit("gallery_empty", f"every scene was dropped: {drops}")
    rows = (len(thumbs) + cols - 1) // cols
    w, h = thumbs[0].size
    sheet = Image.new("RGB", (cols * w, rows * h), (255, 255, 255))
    for k, t in enumerate(thumbs):
        sheet.paste(t, ((k % cols) * w, (k // cols) * h))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() in (".jpg", ".jpeg"):
        sheet.save(out, quality=quality, optimize=True)
    else:
        sheet.save(out)
    return {"out": str(out), "scenes": len(thumbs), "dropped": drops, "bytes": out.stat().st_size}
