"""`refspatial-gen assets sheet`: every asset from six directions with its stored front drawn (PNG).

Why: a semantic front ("the handle side") is only useful if it is right; a person checks a whole
library at a glance, and fixes one with `assets set-front NAME +x "..."` in the axes shown here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera, look_at

VIEWS = [
    ("+x", [1, 0, 0]),
    ("-x", [-1, 0, 0]),
    ("+y", [0, 1, 0]),
    ("-y", [0, -1, 0]),
    ("+z", [0, 0, 1]),
    ("-z", [0, 0, -1]),
]


def _views(centre: np.ndarray, size: float, px: int) -> list[Camera]:
    f = px / 2 / np.tan(np.deg2rad(35) / 2)
    d = 1.1 * size / np.tan(np.deg2rad(35) / 2) + 0.05
    cams = []
    for _, v in VIEWS:
        eye = centre + d * np.asarray(v, float)
        up = np.array([0.0, 1.0, 0.0]) if abs(v[2]) else np.array([0.0, 0.0, 1.0])
        cams.append(Camera(px, px, f, f, px / 2, px / 2, look_at(eye, centre, up), True))
    return cams


def _draw_front(img, cam: Camera, centre: np.ndarray, front: np.ndarray | None, size: float, name: str) -> None:
    from PIL import ImageDraw

    d = ImageDraw.Draw(img)
    d.text((3, 2), f"from {name}", fill=(255, 255, 255))
    if front is None:
        return
    uv, _ = cam.project(np.array([centre, centre + front * 0.75 * size]))
    (x0, y0), (x1, y1) = uv
    if np.hypot(x1 - x0, y1 - y0) < 6:  # looking along the front: a ring at its tip
        r = 8 if np.dot(front, cam.position - centre) > 0 else 4
        d.ellipse([x0 - r, y0 - r, x0 + r, y0 + r], outline=(255, 40, 200), width=3)
        return
    d.line([x0, y0, x1, y1], fill=(255, 40, 200), width=3)
    a = np.arctan2(y1 - y0, x1 - x0)
    for s in (-0.5, 0.5):
        d.line([x1, y1, x1 - 10 * np.cos(a + s), y1 - 10 * np.sin(a + s)], fill=(255, 40, 200), width=3)


def asset_sheet(
    out: str | Path, catalog: str | list | None = None, names: list[str] | None = None, px: int = 160, seed: int = 0
) -> dict[str, Any]:
    """Render the sheet; one row per category: six views, then its name, label, size and front phrase."""
    from PIL import Image, ImageDraw

    from refspatial_gen.assets import build_geometry, load_catalog
    from refspatial_gen.sources.sim.single import render_single, single_object_desc

    cat = load_catalog(catalog or None)
    chosen = names or cat.names()
    rows = []
    for n in chosen:
        c = cat.categories[n]
        rng = np.random.default_rng(seed)
        geo = build_geometry(c, {k: (lo + hi) / 2 for k, (lo, hi) in c.dims.items()}, rng)
        lo, hi = geo.bounds()
        centre, size = (lo + hi) / 2, float((hi - lo).max())
        rgb = cat.colors[c.colors[0]] if c.colors else (0.7, 0.7, 0.7)
        desc = single_object_desc(c, geo, rgb, c.materials[0])
        cams = _views(centre, size, px)
        renders = render_single(desc, cams, cat.materials, cat.colors)
        front = None if c.front is None else np.asarray(c.front, float)
        row = Image.new("RGB", (7 * px, px), (30, 30, 30))
        for k, (r, cam) in enumerate(zip(renders, cams)):
            im = Image.fromarray(np.where(r.instance[..., None] > 0, r.rgb, 60).astype(np.uint8))
            _draw_front(im, cam, centre, front, size, VIEWS[k][0])
            row.paste(im, (k * px, 0))
        d = ImageDraw.Draw(row)
        txt = [
            n,
            f"label: {c.label}",
            "size: " + " x ".join(f"{x:.2f}" for x in hi - lo) + " m",
            f"front: {c.front_phrase}" if c.front is not None else "front: (none)",
            "" if front is None else "  " + ", ".join(f"{x:+.2f}" for x in front),
        ]
        for i, t in enumerate(txt):
            d.text((6 * px + 4, 6 + 14 * i), t[:26], fill=(255, 255, 255))
        rows.append(row)
    sheet = Image.new("RGB", (7 * px, px * max(1, len(rows))), (0, 0, 0))
    for i, r in enumerate(rows):
        sheet.paste(r, (0, i * px))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    return {"out": str(out), "assets": len(rows)}
