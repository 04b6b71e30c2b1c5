"""Builders of everyday objects that hold nothing (fruit, devices, furniture, toys...): shapes.BUILDERS."""

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
    revolve,
    rot_axis,
)


def build_fruit(d: Dims, rng) -> AssetGeometry:
    """A slightly squashed ellipsoid with a flat bottom (so it does not roll forever) and a stem."""
    rx, ry, rz = d["x"] / 2, d.get("y", d["x"]) / 2, d["z"] / 2
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    m.apply_scale([rx, ry, rz])
    v = m.vertices
    v[:, 2] = np.maximum(v[:, 2], -rz * 0.85)
    v[:, 2] += rz * 0.85
    m = trimesh.Trimesh(v, m.faces, process=True)
    parts = [mesh_part(m)]
    if d.get("stem", 0) > 0:
        parts.append(cyl_part((0, 0, 1.85 * rz + 0.006), 0.003, 0.008, role="brown", collide=False))
    return AssetGeometry(parts, density=800)


def build_ball(d: Dims, rng) -> AssetGeometry:
    r = d["d"] / 2
    return AssetGeometry([Part("sphere", (r,), np.array([0, 0, r]))], rolls=True, density=d.get("density", 150))


def build_banana(d: Dims, rng) -> AssetGeometry:
    L, r = d["x"], d["z"] / 2
    n = 5
    parts = []
    pts = []
    for i in range(n + 1):
        a = -0.6 + 1.2 * i / n
        pts.append(np.array([L / 2 / 0.6 * np.sin(a) * 0.95, -L * 0.35 * (1 - np.cos(a)), r]))
    for a, b in zip(pts[:-1], pts[1:]):
        c, v = (a + b) / 2, b - a
        ang = np.arctan2(v[1], v[0])
        R = rot_axis("z", ang) @ rot_axis("y", np.pi / 2)
        parts.append(Part("capsule", (r, np.linalg.norm(v) / 2), c, R))
    return AssetGeometry(parts, density=900)


def build_laptop(d: Dims, rng) -> AssetGeometry:
    x, y, t = d["x"], d["y"], d.get("t", 0.018)
    ang = np.deg2rad(d.get("open_deg", 105 + 15 * rng.random()))
    R = rot_axis("y", -ang)  # lid hinged at the -x edge, opened by `ang` from the base: leaning back
    hinge = np.array([-x / 2, 0, t])
    sc = hinge + R @ np.array([x / 2, 0, -0.004])
    parts = [
        box_part((0, 0, t / 2), (x / 2, y / 2, t / 2)),
        box_part((x * 0.08, 0, t + 0.0005), (x * 0.3, y * 0.42, 0.001), role="black", collide=False),
        box_part(sc, (x / 2, y / 2, 0.004), rot=R),
    ]
    Rz = R @ np.array([0, 0, 1.0])
    parts.append(
        box_part(sc - Rz * 0.0045, (x * 0.45, y * 0.45, 0.0008), rot=R, role="screen", collide=False)
    )  # faces +x
    return AssetGeometry(parts, density=500)


def build_flat_device(d: Dims, rng) -> AssetGeometry:
    """Phones, remotes, keyboards, tablets: a slab with an accent panel on top."""
    x, y, z = d["x"], d["y"], d["z"]
    f = d.get("panel", 0.85)
    parts = [
        box_part((0, 0, z / 2), (x / 2, y / 2, z / 2)),
        box_part(
            (0, 0, z + 0.0005), (x / 2 * f, y / 2 * (f if f < 0.95 else 0.9), 0.001), role="accent", collide=False
        ),
    ]
    return AssetGeometry(parts, flat_top=d.get("flat_top", 0) > 0, density=800)


def build_pen(d: Dims, rng) -> AssetGeometry:
    L, r = d["x"], d["d"] / 2
    prism = trimesh.creation.cylinder(radius=r, height=L * 0.85, sections=6)
    prism.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    prism.apply_translation([-L * 0.075, 0, r])
    tip = trimesh.creation.cone(radius=r * 0.9, height=L * 0.15, sections=12)
    tip.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    tip.apply_translation([L * 0.35, 0, r])
    return AssetGeometry([mesh_part(prism), mesh_part(tip, role="accent")], density=900)


def build_scissors(d: Dims, rng) -> AssetGeometry:
    L, w, t = d["x"], d["y"], 0.008
    parts = []
    for s in (-1, 1):
        R = rot_axis("z", s * 0.08)
        parts.append(box_part(R @ np.array([L * 0.2, 0, t / 2]), (L * 0.3, 0.006, t / 2), rot=R, role="silver"))
        ring = trimesh.creation.annulus(r_min=w * 0.13, r_max=w * 0.25, height=t, sections=16)
        ring.apply_translation([-L * 0.3, s * w * 0.24, t / 2])
        parts.append(mesh_part(ring, collide=False))
        parts.append(box_part((-L * 0.3, s * w * 0.24, t / 2), (w * 0.22, w * 0.22, t / 2), visual=False))
    return AssetGeometry(parts, density=900)


def build_lamp(d: Dims, rng) -> AssetGeometry:
    """A desk lamp: round base, pole, arm reaching to +x, shade opening down (front = the lamp head)."""
    rb, z = d["d"] / 2, d["z"]
    reach = d.get("reach", z * 0.25)
    parts = [
        cyl_part((0, 0, 0.015), rb, 0.015, role="accent", collide=False),
        box_part((0, 0, 0.015), (rb * 0.72, rb * 0.72, 0.015), visual=False),
        cyl_part((0, 0, z * 0.45), 0.008, z * 0.45 - 0.01),
    ]
    parts.append(box_part((reach / 2, 0, z * 0.9), (reach / 2, 0.007, 0.007)))
    shade = revolve([(0, 0), (0.06 * z / 0.4, 0), (0.03, 0.09 * z / 0.4), (0, 0.09 * z / 0.4)])
    shade.apply_translation([reach, 0, z * 0.9 - 0.09 * z / 0.4 * 0.8])
    parts.append(mesh_part(shade))
    return AssetGeometry(parts, density=600)


def build_chair(d: Dims, rng) -> AssetGeometry:
    """A chair facing +x (the side you sit down from); backrest at -x."""
    x, y, sh, bh = d["x"], d["y"], d["seat"], d["z"]
    t, leg = 0.03, 0.02
    parts = [box_part((0, 0, sh - t / 2), (x / 2, y / 2, t / 2))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(
                box_part(
                    (sx * (x / 2 - leg), sy * (y / 2 - leg), (sh - t) / 2), (leg, leg, (sh - t) / 2), role="accent"
                )
            )
    parts.append(box_part((-x / 2 + t / 2, 0, (sh + bh) / 2), (t / 2, y / 2, (bh - sh) / 2)))
    return AssetGeometry(parts, density=250)


def build_stool(d: Dims, rng) -> AssetGeometry:
    r, h = d["d"] / 2, d["z"]
    parts = [cyl_part((0, 0, h - 0.015), r, 0.015)]
    for k in range(4):
        a = np.pi / 4 + k * np.pi / 2
        parts.append(
            box_part(
                (r * 0.65 * np.cos(a), r * 0.65 * np.sin(a), (h - 0.03) / 2),
                (0.015, 0.015, (h - 0.03) / 2),
                role="accent",
            )
        )
    return AssetGeometry(parts, flat_top=True, density=300)


def build_monitor(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]  # x: depth of the stand, y: width of the screen, z: height
    parts = [
        box_part((0, 0, 0.006), (x / 2, y * 0.15, 0.006), role="accent"),
        box_part((-x * 0.2, 0, z * 0.3), (0.01, 0.03, z * 0.3), role="accent"),
        box_part((-x * 0.1, 0, z * 0.62), (0.012, y / 2, z * 0.38 - 0.0)),
        box_part((-x * 0.1 + 0.0125, 0, z * 0.62), (0.0006, y / 2 * 0.94, z * 0.36), role="screen", collide=False),
    ]
    return AssetGeometry(parts, density=400)


def build_toy_car(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    wr = z * 0.22
    parts = [
        box_part((0, 0, wr + z * 0.2), (x / 2, y / 2 * 0.9, z * 0.2)),
        box_part((-x * 0.08, 0, wr + z * 0.55), (x * 0.28, y / 2 * 0.8, z * 0.17), role="accent"),
    ]
    Rw = rot_axis("x", np.pi / 2)
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(cyl_part((sx * x * 0.32, sy * y * 0.45, wr), wr, y * 0.06, role="black", rot=Rw))
    return AssetGeometry(parts, density=300)


def build_duck(d: Dims, rng) -> AssetGeometry:
    x, z = d["x"], d["z"]
    parts = [
        Part("ellipsoid", (x / 2, x * 0.36, z * 0.28), np.array([-x * 0.05, 0, z * 0.28]), collide=False),
        box_part((-x * 0.05, 0, z * 0.25), (x * 0.4, x * 0.28, z * 0.25), visual=False),
        Part("sphere", (z * 0.2,), np.array([x * 0.22, 0, z * 0.72])),
        Part("ellipsoid", (z * 0.1, z * 0.07, z * 0.035), np.array([x * 0.22 + z * 0.22, 0, z * 0.68]), role="orange"),
    ]
    return AssetGeometry(parts, density=200)


def build_teddy(d: Dims, rng) -> AssetGeometry:
    z = d["z"]
    rb, rh = z * 0.28, z * 0.2
    parts = [
        Part("sphere", (rb,), np.array([0, 0, rb])),
        Part("sphere", (rh,), np.array([rb * 0.1, 0, 2 * rb + rh * 0.8])),
        Part("sphere", (rh * 0.35,), np.array([0, rh * 0.75, 2 * rb + rh * 1.6]), collide=False),
        Part("sphere", (rh * 0.35,), np.array([0, -rh * 0.75, 2 * rb + rh * 1.6]), collide=False),
        Part(
            "sphere", (rh * 0.38,), np.array([rb * 0.1 + rh * 0.9, 0, 2 * rb + rh * 0.65]), role="accent", collide=False
        ),
    ]
    for s in (-1, 1):
        parts.append(Part("sphere", (rb * 0.42,), np.array([rb * 0.7, s * rb * 0.6, rb * 0.42])))
    return AssetGeometry(parts, density=150)


def build_frame(d: Dims, rng) -> AssetGeometry:
    """A standing picture frame, picture facing +x, leaning back on a strut."""
    y, z, t = d["y"], d["z"], 0.012
    R = rot_axis("y", -np.deg2rad(12))
    c = np.array([0, 0, z / 2 * np.cos(np.deg2rad(12))])
    parts = [
        box_part(c, (t / 2, y / 2, z / 2), rot=R),
        box_part(
            c + R @ np.array([t / 2 + 0.0008, 0, 0]),
            (0.0006, y / 2 * 0.8, z / 2 * 0.8),
            rot=R,
            role="picture",
            collide=False,
        ),
        box_part((-z * 0.18, 0, z * 0.2), (0.004, 0.01, z * 0.2), rot=rot_axis("y", -0.45), role="accent"),
    ]
    return AssetGeometry(parts, density=500)


def build_clock(d: Dims, rng) -> AssetGeometry:
    r, t = d["d"] / 2, d["x"]
    Ry = rot_axis("y", np.pi / 2)
    parts = [
        cyl_part((0, 0, r), r, t / 2, rot=Ry),
        cyl_part((t / 2 + 0.0006, 0, r), r * 0.85, 0.0006, rot=Ry, role="white", collide=False),
        box_part((-t * 0.2, 0, 0.006), (t * 0.7, r * 0.6, 0.006), role="accent"),
    ]
    return AssetGeometry(parts, density=500)


def build_speaker(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    Ry = rot_axis("y", np.pi / 2)
    parts = [
        box_part((0, 0, z / 2), (x / 2, y / 2, z / 2)),
        cyl_part((x / 2 + 0.0008, 0, z * 0.62), min(y, z) * 0.33, 0.0008, rot=Ry, role="black", collide=False),
        cyl_part((x / 2 + 0.0008, 0, z * 0.22), min(y, z) * 0.15, 0.0008, rot=Ry, role="black", collide=False),
    ]
    return AssetGeometry(parts, flat_top=True, density=500)


def build_camera(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    Ry = rot_axis("y", np.pi / 2)
    parts = [
        box_part((0, 0, z / 2), (x / 2, y / 2, z / 2)),
        cyl_part((x / 2 + x * 0.3, -y * 0.1, z * 0.5), z * 0.35, x * 0.3, rot=Ry, role="black"),
        box_part((-x * 0.1, y * 0.3, z + 0.006), (x * 0.25, y * 0.1, 0.006), role="black"),
    ]
    return AssetGeometry(parts, density=600)


def build_stapler(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    parts = [
        box_part((0, 0, z * 0.15), (x / 2, y / 2, z * 0.15), role="black"),
        box_part((-x * 0.03, 0, z * 0.65), (x * 0.47, y / 2 * 0.85, z * 0.35)),
    ]
    return AssetGeometry(parts, density=900)


def build_plant(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    ph = z * 0.45
    pot = revolve([(0, 0), (r * 0.75, 0), (r, ph), (0, ph)])
    parts = [mesh_part(pot)]
    for k in range(5):
        a = 2 * np.pi * k / 5 + rng.uniform(0, 1)
        rr = r * rng.uniform(0.5, 0.8)
        parts.append(
            Part(
                "sphere",
                (rr,),
                np.array([r * 0.35 * np.cos(a), r * 0.35 * np.sin(a), ph + (z - ph) * rng.uniform(0.35, 0.6)]),
                role="green",
                collide=k == 0,
            )
        )
    parts[-1].collide = True
    return AssetGeometry(parts, density=400)


def build_backpack(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    parts = [
        Part("ellipsoid", (x / 2 * 0.8, y / 2, z / 2), np.array([-x * 0.1, 0, z / 2]), collide=False),
        box_part((-x * 0.1, 0, z / 2), (x / 2 * 0.6, y / 2 * 0.75, z / 2), visual=False),
        box_part((x * 0.25, 0, z * 0.32), (x * 0.15, y * 0.3, z * 0.2), role="accent"),
    ]
    return AssetGeometry(parts, density=150)


def build_mouse(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    m.apply_scale([x / 2, y / 2, z])
    v = m.vertices
    v[:, 2] = np.maximum(v[:, 2], 0.0)
    return AssetGeometry([mesh_part(trimesh.Trimesh(v, m.faces, process=True))], density=500)
