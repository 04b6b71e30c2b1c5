"""Builders of containers and vessels (boxes, cans, bottles, cups, plates, teapots...): shapes.BUILDERS."""

from __future__ import annotations

import numpy as np
import trimesh

from refspatial_gen.assets.parts import (
    AssetGeometry,
    Dims,
    Part,
    box_part,
    cyl_part,
    mesh_part,
    open_vessel,
    revolve,
    rot_axis,
    wall_ring,
)


def build_box(d: Dims, rng) -> AssetGeometry:
    return AssetGeometry(
        [box_part((0, 0, d["z"] / 2), (d["x"] / 2, d["y"] / 2, d["z"] / 2))],
        flat_top=True,
        density=d.get("density", 300),
    )


def build_book(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    c = 0.003
    parts = [
        box_part((0, 0, z / 2), (x / 2, y / 2, z / 2), visual=False),
        box_part((0, 0, c / 2), (x / 2, y / 2, c / 2), collide=False),
        box_part((0, 0, z - c / 2), (x / 2, y / 2, c / 2), collide=False),
        box_part((-x / 2 + c / 2, 0, z / 2), (c / 2, y / 2, z / 2), collide=False),  # spine at -x
        box_part((c / 2, 0, z / 2), (x / 2 - c / 2, y / 2 - c, z / 2 - c), role="paper", collide=False),
    ]
    return AssetGeometry(parts, flat_top=True, density=600)


def build_open_box(d: Dims, rng) -> AssetGeometry:
    x, y, z, w = d["x"], d["y"], d["z"], d.get("wall", 0.006)
    parts = [
        box_part((0, 0, w / 2), (x / 2, y / 2, w / 2)),
        box_part((x / 2 - w / 2, 0, z / 2), (w / 2, y / 2, z / 2)),
        box_part((-x / 2 + w / 2, 0, z / 2), (w / 2, y / 2, z / 2)),
        box_part((0, y / 2 - w / 2, z / 2), (x / 2 - w, w / 2, z / 2)),
        box_part((0, -y / 2 + w / 2, z / 2), (x / 2 - w, w / 2, z / 2)),
    ]
    cav = (np.array([0, 0, (z + w) / 2]), np.array([x - 2 * w, y - 2 * w, z - w]))
    return AssetGeometry(parts, cavity=cav, density=400)


def build_cylinder(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    parts = [cyl_part((0, 0, z / 2), r, z / 2)]
    if d.get("lid", 0) > 0:
        parts.append(cyl_part((0, 0, z + d["lid"] / 2), r * 1.02, d["lid"] / 2, role="accent"))
    return AssetGeometry(parts, flat_top=True, density=d.get("density", 400))


def build_can(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    parts = [
        cyl_part((0, 0, z / 2), r, z / 2 - 0.004),
        cyl_part((0, 0, 0.002), r * 0.94, 0.002, role="silver"),
        cyl_part((0, 0, z - 0.002), r * 0.94, 0.002, role="silver"),
    ]
    return AssetGeometry(parts, flat_top=True, density=300)


def build_bottle(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    neck = d.get("neck", 0.3)
    rn = r * 0.38
    prof = [
        (0, 0),
        (r * 0.92, 0),
        (r, 0.03 * z),
        (r, (1 - neck) * z),
        (rn, (1 - neck * 0.45) * z),
        (rn, 0.93 * z),
        (0, 0.93 * z),
    ]
    parts = [mesh_part(revolve(prof)), cyl_part((0, 0, 0.965 * z), rn * 1.12, 0.035 * z, role="accent")]
    return AssetGeometry(parts, density=250)


def build_vase(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    b = 0.6 + 0.3 * rng.random()
    prof = [
        (0, 0),
        (r * 0.7, 0),
        (r, 0.35 * z),
        (r * b * 0.6, 0.8 * z),
        (r * 0.55, z),
        (r * 0.45, z),
        (r * 0.4, 0.82 * z),
        (0, 0.82 * z),
    ]
    return AssetGeometry([mesh_part(revolve(prof))], density=700)


def build_vessel(d: Dims, rng) -> AssetGeometry:
    """Cups, glasses, bowls, bins, pots: open revolved containers."""
    rt, z = d["d"] / 2, d["z"]
    rb = rt * d.get("taper", 0.8)
    parts, cav = open_vessel(rb, rt, z, d.get("wall", 0.004), d.get("bottom", 0.006), d.get("curve", 0.0))
    return AssetGeometry(parts, cavity=cav, density=900)


def build_plate(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    prof = [(0, 0), (r * 0.7, 0), (r, z), (r * 0.93, z), (r * 0.68, z * 0.45), (0, z * 0.45)]
    parts = [mesh_part(revolve(prof, 36), collide=False), cyl_part((0, 0, z * 0.25), r * 0.7, z * 0.25, visual=False)]
    parts += wall_ring(r * 0.7, 0, r * 0.97, z, z * 0.5, n=16)
    return AssetGeometry(parts, flat_top=True, density=900)


def _handle(x0: float, zc: float, hh: float, reach: float, t: float, sign: float = 1.0) -> list[Part]:
    """A C-shaped handle on the side at x = x0 (sign=+1: +x), as three boxes."""
    s = sign
    return [
        box_part((x0 + s * reach / 2, 0, zc + hh - t / 2), (reach / 2, t / 2, t / 2)),
        box_part((x0 + s * reach / 2, 0, zc - hh + t / 2), (reach / 2, t / 2, t / 2)),
        box_part((x0 + s * (reach - t / 2), 0, zc), (t / 2, t / 2, hh)),
    ]


def build_mug(d: Dims, rng) -> AssetGeometry:
    geo = build_vessel({**d, "taper": d.get("taper", 0.95)}, rng)
    r, z = d["d"] / 2, d["z"]
    geo.parts += _handle(r * 0.95, z * 0.55, z * 0.28, 0.028, 0.009)
    return geo


def build_spouted(d: Dims, rng) -> AssetGeometry:
    """Teapots, kettles, jugs: a closed revolved body, a spout at +x and a handle at -x."""
    r, z = d["d"] / 2, d["z"]
    kind = d.get("shape", 0)
    if kind == 0:  # teapot
        prof = [(0, 0), (r * 0.7, 0), (r, 0.4 * z), (r * 0.75, 0.8 * z), (r * 0.3, 0.85 * z), (r * 0.12, z), (0, z)]
    else:  # kettle / jug
        prof = [(0, 0), (r, 0), (r * 0.95, 0.55 * z), (r * 0.7, 0.9 * z), (0, 0.9 * z)]
    parts = [mesh_part(revolve(prof))]
    sp = trimesh.creation.cylinder(radius=r * 0.12, height=r * 0.9, sections=12)
    R = rot_axis("y", np.deg2rad(55))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [r * 1.05, 0, 0.5 * z]
    sp.apply_transform(T)
    parts.append(mesh_part(sp))
    parts += _handle(-r * 0.85, 0.5 * z, 0.25 * z, r * 0.55, 0.012, sign=-1.0)
    return AssetGeometry(parts, density=500)


def build_spray(d: Dims, rng) -> AssetGeometry:
    geo = build_bottle({**d, "neck": 0.2}, rng)
    z, r = d["z"], d["d"] / 2
    geo.parts.append(box_part((r * 0.25, 0, z + 0.02), (r * 0.8, 0.012, 0.018), role="accent"))
    return geo


def build_carton(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    roof = trimesh.Trimesh(
        vertices=[
            [-x / 2, -y / 2, 0],
            [x / 2, -y / 2, 0],
            [x / 2, y / 2, 0],
            [-x / 2, y / 2, 0],
            [0, -y / 2, x * 0.4],
            [0, y / 2, x * 0.4],
        ],
        faces=[[0, 1, 4], [1, 2, 5], [1, 5, 4], [2, 3, 5], [3, 0, 4], [3, 4, 5], [0, 3, 2], [0, 2, 1]],
    )
    roof.apply_translation([0, 0, z * 0.85])
    return AssetGeometry(
        [box_part((0, 0, z * 0.425), (x / 2, y / 2, z * 0.425)), mesh_part(roof, role="accent")], density=400
    )


def build_wineglass(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    prof = [
        (0, 0),
        (r * 0.85, 0),
        (r * 0.85, 0.02 * z),
        (0.005, 0.05 * z),
        (0.005, 0.5 * z),
        (r * 0.8, 0.62 * z),
        (r, z),
        (r * 0.93, z),
        (r * 0.72, 0.65 * z),
        (0, 0.56 * z),
    ]
    return AssetGeometry(
        [
            mesh_part(revolve(prof), collide=False),
            cyl_part((0, 0, 0.01 * z), r * 0.85, 0.01 * z, visual=False),
            cyl_part((0, 0, 0.3 * z), 0.006, 0.28 * z, visual=False),
            mesh_part(revolve([(0, 0.5 * z), (r * 0.8, 0.62 * z), (r, z), (0, z)]), visual=False),
        ],
        density=600,
    )
