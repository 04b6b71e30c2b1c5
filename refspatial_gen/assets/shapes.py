"""Procedural object geometry: visual meshes plus collision pieces built from convex primitives.

Why convex pieces: MuJoCo collides every mesh as its convex hull, so a cup given as one mesh is a solid
cylinder and nothing can go inside it. Building concave shapes (cups, bowls, open boxes, trays) from
boxes and cylinders is deterministic, costs nothing at run time (no decomposition, no cache) and lets
objects rest inside containers.

Object frame: origin at the bottom centre, z up, +x is the side a category's semantic front refers to
(e.g. the mug handle), metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable

import numpy as np
import trimesh

Dims = dict[str, float]


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion (w, x, y, z), MuJoCo order."""
    R = np.asarray(R, float)
    t = np.trace(R)
    if t > 0:
        s = np.sqrt(t + 1.0) * 2
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)


def matrix_from_quat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rot_axis(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@dataclass
class Part:
    """One geom of an object. `kind` is a MuJoCo geom type; sizes use MuJoCo semantics (half extents,
    radius / half height). `mesh` is set for kind "mesh" (vertices in the part frame). `role` picks the
    colour: "body" (the instance colour), "accent" (a second colour) or a fixed colour word.
    A part with collide=False is drawn only; visual=False is collided only (hidden)."""

    kind: str
    size: tuple[float, ...] = ()
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rot: np.ndarray = field(default_factory=lambda: np.eye(3))
    mesh: trimesh.Trimesh | None = None
    role: str = "body"
    visual: bool = True
    collide: bool = True
    uv: np.ndarray | None = None  # per-vertex texture coordinates of `mesh` (external textured meshes)
    texture: str | None = None  # where the texture for `uv` came from (image file, or "<mesh file>#<n>" if embedded)
    texture_img: np.ndarray | None = None  # its pixels, uint8 HxWx3, first row = top of the image (v = 1)
    rgba: tuple[float, float, float, float] | None = None  # an authored fixed colour (overrides `role`)

    def trimesh(self) -> trimesh.Trimesh:
        """This part as a triangle mesh in the object frame (for boxes, silhouettes and USD); built once."""
        if getattr(self, "_tm", None) is None:
            self._tm = self._make_trimesh()
        return self._tm

    def _make_trimesh(self) -> trimesh.Trimesh:
        if self.kind == "mesh":
            v, f = np.asarray(self.mesh.vertices, float), np.asarray(self.mesh.faces)
        elif self.kind == "capsule":
            m = trimesh.creation.capsule(radius=self.size[0], height=2 * self.size[1], count=[12, 12])
            v, f = np.asarray(m.vertices), np.asarray(m.faces)
        else:
            uv, f = _unit_mesh(self.kind)
            scale = {"box": lambda z: np.asarray(z[:3]), "cylinder": lambda z: np.array([z[0], z[0], z[1]]),
                     "sphere": lambda z: np.array([z[0]] * 3), "ellipsoid": lambda z: np.asarray(z[:3])}
            if self.kind not in scale:
                raise ValueError(f"unknown part kind {self.kind}")
            v = uv * scale[self.kind](self.size)
        return trimesh.Trimesh(v @ np.asarray(self.rot).T + self.pos, f, process=False)


@lru_cache(maxsize=8)
def _unit_mesh(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Unit primitives (half extent / radius 1), built once per process and scaled per part."""
    if kind == "box":
        m = trimesh.creation.box(extents=[2, 2, 2])
    elif kind == "cylinder":
        m = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=24)
    else:
        m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    v, f = np.asarray(m.vertices, float), np.asarray(m.faces)
    v.flags.writeable = False
    return v, f


@dataclass
class AssetGeometry:
    """A built object instance: its parts and what layouts need to know about its shape."""

    parts: list[Part]
    cavity: tuple[np.ndarray, np.ndarray] | None = None  # (centre, size) of the inside of a container
    flat_top: bool = False  # other objects can stand on its top
    rolls: bool = False  # round: give it rolling friction
    density: float = 500.0  # kg/m^3 of the solid parts
    _hull: np.ndarray | None = None
    _outline: np.ndarray | None = None

    def hull_points(self) -> np.ndarray:
        """Vertices of the convex hull of all drawn parts, object frame (N, 3)."""
        if self._hull is None:
            from scipy.spatial import ConvexHull, QhullError

            pts = np.concatenate([p.trimesh().vertices for p in self.parts if p.visual])
            try:
                self._hull = pts[np.sort(ConvexHull(pts).vertices)]
            except QhullError as e:  # flat or degenerate geometry
                raise ValueError(f"degenerate object geometry: {e}") from e
        return self._hull

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        h = self.hull_points()
        return h.min(axis=0), h.max(axis=0)


# ----------------------------------------------------------------------------------------- helpers

def _mesh_part(m: trimesh.Trimesh, role: str = "body", collide: bool = True, visual: bool = True) -> Part:
    return Part("mesh", (), np.zeros(3), np.eye(3), m, role, visual, collide)


def revolve(profile: list[tuple[float, float]], sections: int = 28) -> trimesh.Trimesh:
    """Revolve an (r, z) polyline about z. A closed profile that starts and ends on the axis gives a
    watertight solid; give it counter-clockwise in the (r, z) plane."""
    return trimesh.creation.revolve(np.asarray(profile, float), sections=sections)


def _box(center, half, role="body", rot=None, visual=True, collide=True) -> Part:
    return Part("box", tuple(float(h) for h in half), np.asarray(center, float),
                np.eye(3) if rot is None else rot, None, role, visual, collide)


def _cyl(center, r, half_h, role="body", rot=None, visual=True, collide=True) -> Part:
    return Part("cylinder", (float(r), float(half_h)), np.asarray(center, float),
                np.eye(3) if rot is None else rot, None, role, visual, collide)


def _wall_ring(r0: float, z0: float, r1: float, z1: float, thick: float, n: int = 12) -> list[Part]:
    """Hidden collision boxes approximating a revolved wall from (r0, z0) to (r1, z1)."""
    parts = []
    seg = np.hypot(r1 - r0, z1 - z0)
    tilt = np.arctan2(r1 - r0, z1 - z0)  # lean outwards
    rm, zm = (r0 + r1) / 2, (z0 + z1) / 2
    half_w = (max(r0, r1) + thick) * np.sin(np.pi / n) * 1.08
    for k in range(n):
        a = 2 * np.pi * k / n
        R = rot_axis("z", a) @ rot_axis("y", tilt)
        c = np.array([rm * np.cos(a), rm * np.sin(a), zm])
        parts.append(_box(c, (thick / 2, half_w, seg / 2), rot=R, visual=False))
    return parts


def _open_vessel(r_bot: float, r_top: float, h: float, wall: float, bottom: float, curve: float = 0.0,
                 sections: int = 28) -> tuple[list[Part], tuple[np.ndarray, np.ndarray]]:
    """A cup/bowl/bin: smooth visual mesh, collision base + wall rings; returns parts and cavity."""
    n_mid = 4 if curve > 0 else 1
    outer = []
    for i in range(n_mid + 1):
        t = i / n_mid
        r = r_bot + (r_top - r_bot) * (t ** (1 - curve) if curve > 0 else t)
        outer.append((r, h * t))
    inner = [(max(r - wall, 1e-3), max(z, bottom)) for r, z in outer[::-1]]
    profile = [(0.0, 0.0)] + outer + inner + [(0.0, bottom)]
    # revolve wants counter-clockwise (r, z): axis bottom -> out -> up -> in -> down -> axis
    vis = revolve(profile, sections)
    parts = [_mesh_part(vis, collide=False)]
    parts.append(_cyl((0, 0, bottom / 2), r_bot, bottom / 2, visual=False))
    for a, b in zip(outer[:-1], outer[1:]):
        parts += _wall_ring(a[0] - wall / 2, a[1], b[0] - wall / 2, b[1], wall, n=12)
    rin = max(r_bot - wall, 0.005)
    cav = (np.array([0, 0, (bottom + h) / 2]), np.array([2 * rin, 2 * rin, h - bottom]))
    return parts, cav


# ----------------------------------------------------------------------------------------- builders

def build_box(d: Dims, rng) -> AssetGeometry:
    return AssetGeometry([_box((0, 0, d["z"] / 2), (d["x"] / 2, d["y"] / 2, d["z"] / 2))], flat_top=True,
                         density=d.get("density", 300))


def build_book(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    c = 0.003
    parts = [_box((0, 0, z / 2), (x / 2, y / 2, z / 2), visual=False),
             _box((0, 0, c / 2), (x / 2, y / 2, c / 2), collide=False),
             _box((0, 0, z - c / 2), (x / 2, y / 2, c / 2), collide=False),
             _box((-x / 2 + c / 2, 0, z / 2), (c / 2, y / 2, z / 2), collide=False),  # spine at -x
             _box((c / 2, 0, z / 2), (x / 2 - c / 2, y / 2 - c, z / 2 - c), role="paper", collide=False)]
    return AssetGeometry(parts, flat_top=True, density=600)


def build_open_box(d: Dims, rng) -> AssetGeometry:
    x, y, z, w = d["x"], d["y"], d["z"], d.get("wall", 0.006)
    parts = [_box((0, 0, w / 2), (x / 2, y / 2, w / 2)),
             _box((x / 2 - w / 2, 0, z / 2), (w / 2, y / 2, z / 2)), _box((-x / 2 + w / 2, 0, z / 2), (w / 2, y / 2, z / 2)),
             _box((0, y / 2 - w / 2, z / 2), (x / 2 - w, w / 2, z / 2)), _box((0, -y / 2 + w / 2, z / 2), (x / 2 - w, w / 2, z / 2))]
    cav = (np.array([0, 0, (z + w) / 2]), np.array([x - 2 * w, y - 2 * w, z - w]))
    return AssetGeometry(parts, cavity=cav, density=400)


def build_cylinder(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    parts = [_cyl((0, 0, z / 2), r, z / 2)]
    if d.get("lid", 0) > 0:
        parts.append(_cyl((0, 0, z + d["lid"] / 2), r * 1.02, d["lid"] / 2, role="accent"))
    return AssetGeometry(parts, flat_top=True, density=d.get("density", 400))


def build_can(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    parts = [_cyl((0, 0, z / 2), r, z / 2 - 0.004), _cyl((0, 0, 0.002), r * 0.94, 0.002, role="silver"),
             _cyl((0, 0, z - 0.002), r * 0.94, 0.002, role="silver")]
    return AssetGeometry(parts, flat_top=True, density=300)


def build_bottle(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    neck = d.get("neck", 0.3)
    rn = r * 0.38
    prof = [(0, 0), (r * 0.92, 0), (r, 0.03 * z), (r, (1 - neck) * z), (rn, (1 - neck * 0.45) * z), (rn, 0.93 * z), (0, 0.93 * z)]
    parts = [_mesh_part(revolve(prof)), _cyl((0, 0, 0.965 * z), rn * 1.12, 0.035 * z, role="accent")]
    return AssetGeometry(parts, density=250)


def build_vase(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    b = 0.6 + 0.3 * rng.random()
    prof = [(0, 0), (r * 0.7, 0), (r, 0.35 * z), (r * b * 0.6, 0.8 * z), (r * 0.55, z), (r * 0.45, z), (r * 0.4, 0.82 * z), (0, 0.82 * z)]
    return AssetGeometry([_mesh_part(revolve(prof))], density=700)


def build_vessel(d: Dims, rng) -> AssetGeometry:
    """Cups, glasses, bowls, bins, pots: open revolved containers."""
    rt, z = d["d"] / 2, d["z"]
    rb = rt * d.get("taper", 0.8)
    parts, cav = _open_vessel(rb, rt, z, d.get("wall", 0.004), d.get("bottom", 0.006), d.get("curve", 0.0))
    return AssetGeometry(parts, cavity=cav, density=900)


def build_plate(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    prof = [(0, 0), (r * 0.7, 0), (r, z), (r * 0.93, z), (r * 0.68, z * 0.45), (0, z * 0.45)]
    parts = [_mesh_part(revolve(prof, 36), collide=False), _cyl((0, 0, z * 0.25), r * 0.7, z * 0.25, visual=False)]
    parts += _wall_ring(r * 0.7, 0, r * 0.97, z, z * 0.5, n=16)
    return AssetGeometry(parts, flat_top=True, density=900)


def _handle(x0: float, zc: float, hh: float, reach: float, t: float, sign: float = 1.0) -> list[Part]:
    """A C-shaped handle on the side at x = x0 (sign=+1: +x), as three boxes."""
    s = sign
    return [_box((x0 + s * reach / 2, 0, zc + hh - t / 2), (reach / 2, t / 2, t / 2)),
            _box((x0 + s * reach / 2, 0, zc - hh + t / 2), (reach / 2, t / 2, t / 2)),
            _box((x0 + s * (reach - t / 2), 0, zc), (t / 2, t / 2, hh))]


def build_mug(d: Dims, rng) -> AssetGeometry:
    geo = build_vessel({**d, "taper": d.get("taper", 0.95)}, rng)
    r, z = d["d"] / 2, d["z"]
    geo.parts += _handle(r * 0.95, z * 0.55, z * 0.28, 0.028, 0.009)
    return geo


def build_fruit(d: Dims, rng) -> AssetGeometry:
    """A slightly squashed ellipsoid with a flat bottom (so it does not roll forever) and a stem."""
    rx, ry, rz = d["x"] / 2, d.get("y", d["x"]) / 2, d["z"] / 2
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    m.apply_scale([rx, ry, rz])
    v = m.vertices
    v[:, 2] = np.maximum(v[:, 2], -rz * 0.85)
    v[:, 2] += rz * 0.85
    m = trimesh.Trimesh(v, m.faces, process=True)
    parts = [_mesh_part(m)]
    if d.get("stem", 0) > 0:
        parts.append(_cyl((0, 0, 1.85 * rz + 0.006), 0.003, 0.008, role="brown", collide=False))
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
    parts = [_box((0, 0, t / 2), (x / 2, y / 2, t / 2)),
             _box((x * 0.08, 0, t + 0.0005), (x * 0.3, y * 0.42, 0.001), role="black", collide=False),
             _box(sc, (x / 2, y / 2, 0.004), rot=R)]
    Rz = R @ np.array([0, 0, 1.0])
    parts.append(_box(sc - Rz * 0.0045, (x * 0.45, y * 0.45, 0.0008), rot=R, role="screen", collide=False))  # faces +x
    return AssetGeometry(parts, density=500)


def build_flat_device(d: Dims, rng) -> AssetGeometry:
    """Phones, remotes, keyboards, tablets: a slab with an accent panel on top."""
    x, y, z = d["x"], d["y"], d["z"]
    f = d.get("panel", 0.85)
    parts = [_box((0, 0, z / 2), (x / 2, y / 2, z / 2)),
             _box((0, 0, z + 0.0005), (x / 2 * f, y / 2 * (f if f < 0.95 else 0.9), 0.001), role="accent", collide=False)]
    return AssetGeometry(parts, flat_top=d.get("flat_top", 0) > 0, density=800)


def build_pen(d: Dims, rng) -> AssetGeometry:
    L, r = d["x"], d["d"] / 2
    prism = trimesh.creation.cylinder(radius=r, height=L * 0.85, sections=6)
    prism.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    prism.apply_translation([-L * 0.075, 0, r])
    tip = trimesh.creation.cone(radius=r * 0.9, height=L * 0.15, sections=12)
    tip.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    tip.apply_translation([L * 0.35, 0, r])
    return AssetGeometry([_mesh_part(prism), _mesh_part(tip, role="accent")], density=900)


def build_scissors(d: Dims, rng) -> AssetGeometry:
    L, w, t = d["x"], d["y"], 0.008
    parts = []
    for s in (-1, 1):
        R = rot_axis("z", s * 0.08)
        parts.append(_box(R @ np.array([L * 0.2, 0, t / 2]), (L * 0.3, 0.006, t / 2), rot=R, role="silver"))
        ring = trimesh.creation.annulus(r_min=w * 0.13, r_max=w * 0.25, height=t, sections=16)
        ring.apply_translation([-L * 0.3, s * w * 0.24, t / 2])
        parts.append(_mesh_part(ring, collide=False))
        parts.append(_box((-L * 0.3, s * w * 0.24, t / 2), (w * 0.22, w * 0.22, t / 2), visual=False))
    return AssetGeometry(parts, density=900)


def build_spouted(d: Dims, rng) -> AssetGeometry:
    """Teapots, kettles, jugs: a closed revolved body, a spout at +x and a handle at -x."""
    r, z = d["d"] / 2, d["z"]
    kind = d.get("shape", 0)
    if kind == 0:  # teapot
        prof = [(0, 0), (r * 0.7, 0), (r, 0.4 * z), (r * 0.75, 0.8 * z), (r * 0.3, 0.85 * z), (r * 0.12, z), (0, z)]
    else:  # kettle / jug
        prof = [(0, 0), (r, 0), (r * 0.95, 0.55 * z), (r * 0.7, 0.9 * z), (0, 0.9 * z)]
    parts = [_mesh_part(revolve(prof))]
    sp = trimesh.creation.cylinder(radius=r * 0.12, height=r * 0.9, sections=12)
    R = rot_axis("y", np.deg2rad(55))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [r * 1.05, 0, 0.5 * z]
    sp.apply_transform(T)
    parts.append(_mesh_part(sp))
    parts += _handle(-r * 0.85, 0.5 * z, 0.25 * z, r * 0.55, 0.012, sign=-1.0)
    return AssetGeometry(parts, density=500)


def build_lamp(d: Dims, rng) -> AssetGeometry:
    """A desk lamp: round base, pole, arm reaching to +x, shade opening down (front = the lamp head)."""
    rb, z = d["d"] / 2, d["z"]
    reach = d.get("reach", z * 0.25)
    parts = [_cyl((0, 0, 0.015), rb, 0.015, role="accent", collide=False), _box((0, 0, 0.015), (rb * 0.72, rb * 0.72, 0.015), visual=False),
             _cyl((0, 0, z * 0.45), 0.008, z * 0.45 - 0.01)]
    parts.append(_box((reach / 2, 0, z * 0.9), (reach / 2, 0.007, 0.007)))
    shade = revolve([(0, 0), (0.06 * z / 0.4, 0), (0.03, 0.09 * z / 0.4), (0, 0.09 * z / 0.4)])
    shade.apply_translation([reach, 0, z * 0.9 - 0.09 * z / 0.4 * 0.8])
    parts.append(_mesh_part(shade))
    return AssetGeometry(parts, density=600)


def build_chair(d: Dims, rng) -> AssetGeometry:
    """A chair facing +x (the side you sit down from); backrest at -x."""
    x, y, sh, bh = d["x"], d["y"], d["seat"], d["z"]
    t, leg = 0.03, 0.02
    parts = [_box((0, 0, sh - t / 2), (x / 2, y / 2, t / 2))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_box((sx * (x / 2 - leg), sy * (y / 2 - leg), (sh - t) / 2), (leg, leg, (sh - t) / 2), role="accent"))
    parts.append(_box((-x / 2 + t / 2, 0, (sh + bh) / 2), (t / 2, y / 2, (bh - sh) / 2)))
    return AssetGeometry(parts, density=250)


def build_stool(d: Dims, rng) -> AssetGeometry:
    r, h = d["d"] / 2, d["z"]
    parts = [_cyl((0, 0, h - 0.015), r, 0.015)]
    for k in range(4):
        a = np.pi / 4 + k * np.pi / 2
        parts.append(_box((r * 0.65 * np.cos(a), r * 0.65 * np.sin(a), (h - 0.03) / 2), (0.015, 0.015, (h - 0.03) / 2), role="accent"))
    return AssetGeometry(parts, flat_top=True, density=300)


def build_monitor(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]  # x: depth of the stand, y: width of the screen, z: height
    parts = [_box((0, 0, 0.006), (x / 2, y * 0.15, 0.006), role="accent"), _box((-x * 0.2, 0, z * 0.3), (0.01, 0.03, z * 0.3), role="accent"),
             _box((-x * 0.1, 0, z * 0.62), (0.012, y / 2, z * 0.38 - 0.0)),
             _box((-x * 0.1 + 0.0125, 0, z * 0.62), (0.0006, y / 2 * 0.94, z * 0.36), role="screen", collide=False)]
    return AssetGeometry(parts, density=400)


def build_toy_car(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    wr = z * 0.22
    parts = [_box((0, 0, wr + z * 0.2), (x / 2, y / 2 * 0.9, z * 0.2)), _box((-x * 0.08, 0, wr + z * 0.55), (x * 0.28, y / 2 * 0.8, z * 0.17), role="accent")]
    Rw = rot_axis("x", np.pi / 2)
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_cyl((sx * x * 0.32, sy * y * 0.45, wr), wr, y * 0.06, role="black", rot=Rw))
    return AssetGeometry(parts, density=300)


def build_duck(d: Dims, rng) -> AssetGeometry:
    x, z = d["x"], d["z"]
    parts = [Part("ellipsoid", (x / 2, x * 0.36, z * 0.28), np.array([-x * 0.05, 0, z * 0.28]), collide=False),
             _box((-x * 0.05, 0, z * 0.25), (x * 0.4, x * 0.28, z * 0.25), visual=False),
             Part("sphere", (z * 0.2,), np.array([x * 0.22, 0, z * 0.72])),
             Part("ellipsoid", (z * 0.1, z * 0.07, z * 0.035), np.array([x * 0.22 + z * 0.22, 0, z * 0.68]), role="orange")]
    return AssetGeometry(parts, density=200)


def build_teddy(d: Dims, rng) -> AssetGeometry:
    z = d["z"]
    rb, rh = z * 0.28, z * 0.2
    parts = [Part("sphere", (rb,), np.array([0, 0, rb])), Part("sphere", (rh,), np.array([rb * 0.1, 0, 2 * rb + rh * 0.8])),
             Part("sphere", (rh * 0.35,), np.array([0, rh * 0.75, 2 * rb + rh * 1.6]), collide=False),
             Part("sphere", (rh * 0.35,), np.array([0, -rh * 0.75, 2 * rb + rh * 1.6]), collide=False),
             Part("sphere", (rh * 0.38,), np.array([rb * 0.1 + rh * 0.9, 0, 2 * rb + rh * 0.65]), role="accent", collide=False)]
    for s in (-1, 1):
        parts.append(Part("sphere", (rb * 0.42,), np.array([rb * 0.7, s * rb * 0.6, rb * 0.42])))
    return AssetGeometry(parts, density=150)


def build_frame(d: Dims, rng) -> AssetGeometry:
    """A standing picture frame, picture facing +x, leaning back on a strut."""
    y, z, t = d["y"], d["z"], 0.012
    R = rot_axis("y", -np.deg2rad(12))
    c = np.array([0, 0, z / 2 * np.cos(np.deg2rad(12))])
    parts = [_box(c, (t / 2, y / 2, z / 2), rot=R),
             _box(c + R @ np.array([t / 2 + 0.0008, 0, 0]), (0.0006, y / 2 * 0.8, z / 2 * 0.8), rot=R, role="picture", collide=False),
             _box((-z * 0.18, 0, z * 0.2), (0.004, 0.01, z * 0.2), rot=rot_axis("y", -0.45), role="accent")]
    return AssetGeometry(parts, density=500)


def build_clock(d: Dims, rng) -> AssetGeometry:
    r, t = d["d"] / 2, d["x"]
    Ry = rot_axis("y", np.pi / 2)
    parts = [_cyl((0, 0, r), r, t / 2, rot=Ry), _cyl((t / 2 + 0.0006, 0, r), r * 0.85, 0.0006, rot=Ry, role="white", collide=False),
             _box((-t * 0.2, 0, 0.006), (t * 0.7, r * 0.6, 0.006), role="accent")]
    return AssetGeometry(parts, density=500)


def build_speaker(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    Ry = rot_axis("y", np.pi / 2)
    parts = [_box((0, 0, z / 2), (x / 2, y / 2, z / 2)),
             _cyl((x / 2 + 0.0008, 0, z * 0.62), min(y, z) * 0.33, 0.0008, rot=Ry, role="black", collide=False),
             _cyl((x / 2 + 0.0008, 0, z * 0.22), min(y, z) * 0.15, 0.0008, rot=Ry, role="black", collide=False)]
    return AssetGeometry(parts, flat_top=True, density=500)


def build_camera(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    Ry = rot_axis("y", np.pi / 2)
    parts = [_box((0, 0, z / 2), (x / 2, y / 2, z / 2)),
             _cyl((x / 2 + x * 0.3, -y * 0.1, z * 0.5), z * 0.35, x * 0.3, rot=Ry, role="black"),
             _box((-x * 0.1, y * 0.3, z + 0.006), (x * 0.25, y * 0.1, 0.006), role="black")]
    return AssetGeometry(parts, density=600)


def build_stapler(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    parts = [_box((0, 0, z * 0.15), (x / 2, y / 2, z * 0.15), role="black"), _box((-x * 0.03, 0, z * 0.65), (x * 0.47, y / 2 * 0.85, z * 0.35))]
    return AssetGeometry(parts, density=900)


def build_spray(d: Dims, rng) -> AssetGeometry:
    geo = build_bottle({**d, "neck": 0.2}, rng)
    z, r = d["z"], d["d"] / 2
    geo.parts.append(_box((r * 0.25, 0, z + 0.02), (r * 0.8, 0.012, 0.018), role="accent"))
    return geo


def build_plant(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    ph = z * 0.45
    pot = revolve([(0, 0), (r * 0.75, 0), (r, ph), (0, ph)])
    parts = [_mesh_part(pot)]
    for k in range(5):
        a = 2 * np.pi * k / 5 + rng.uniform(0, 1)
        rr = r * rng.uniform(0.5, 0.8)
        parts.append(Part("sphere", (rr,), np.array([r * 0.35 * np.cos(a), r * 0.35 * np.sin(a), ph + (z - ph) * rng.uniform(0.35, 0.6)]),
                          role="green", collide=k == 0))
    parts[-1].collide = True
    return AssetGeometry(parts, density=400)


def build_carton(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    roof = trimesh.Trimesh(vertices=[[-x / 2, -y / 2, 0], [x / 2, -y / 2, 0], [x / 2, y / 2, 0], [-x / 2, y / 2, 0], [0, -y / 2, x * 0.4], [0, y / 2, x * 0.4]],
                           faces=[[0, 1, 4], [1, 2, 5], [1, 5, 4], [2, 3, 5], [3, 0, 4], [3, 4, 5], [0, 3, 2], [0, 2, 1]])
    roof.apply_translation([0, 0, z * 0.85])
    return AssetGeometry([_box((0, 0, z * 0.425), (x / 2, y / 2, z * 0.425)), _mesh_part(roof, role="accent")], density=400)


def build_backpack(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    parts = [Part("ellipsoid", (x / 2 * 0.8, y / 2, z / 2), np.array([-x * 0.1, 0, z / 2]), collide=False),
             _box((-x * 0.1, 0, z / 2), (x / 2 * 0.6, y / 2 * 0.75, z / 2), visual=False),
             _box((x * 0.25, 0, z * 0.32), (x * 0.15, y * 0.3, z * 0.2), role="accent")]
    return AssetGeometry(parts, density=150)


def build_mouse(d: Dims, rng) -> AssetGeometry:
    x, y, z = d["x"], d["y"], d["z"]
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    m.apply_scale([x / 2, y / 2, z])
    v = m.vertices
    v[:, 2] = np.maximum(v[:, 2], 0.0)
    return AssetGeometry([_mesh_part(trimesh.Trimesh(v, m.faces, process=True))], density=500)


def build_wineglass(d: Dims, rng) -> AssetGeometry:
    r, z = d["d"] / 2, d["z"]
    prof = [(0, 0), (r * 0.85, 0), (r * 0.85, 0.02 * z), (0.005, 0.05 * z), (0.005, 0.5 * z), (r * 0.8, 0.62 * z), (r, z), (r * 0.93, z),
            (r * 0.72, 0.65 * z), (0, 0.56 * z)]
    return AssetGeometry([_mesh_part(revolve(prof), collide=False), _cyl((0, 0, 0.01 * z), r * 0.85, 0.01 * z, visual=False),
                          _cyl((0, 0, 0.3 * z), 0.006, 0.28 * z, visual=False),
                          _mesh_part(revolve([(0, 0.5 * z), (r * 0.8, 0.62 * z), (r, z), (0, z)]), visual=False)], density=600)


BUILDERS: dict[str, Callable[[Dims, np.random.Generator], AssetGeometry]] = {
    "box": build_box, "book": build_book, "open_box": build_open_box, "cylinder": build_cylinder, "can": build_can,
    "bottle": build_bottle, "vase": build_vase, "vessel": build_vessel, "plate": build_plate, "mug": build_mug,
    "fruit": build_fruit, "ball": build_ball, "banana": build_banana, "laptop": build_laptop,
    "flat_device": build_flat_device, "pen": build_pen, "scissors": build_scissors, "spouted": build_spouted,
    "lamp": build_lamp, "chair": build_chair, "stool": build_stool, "monitor": build_monitor, "toy_car": build_toy_car,
    "duck": build_duck, "teddy": build_teddy, "frame": build_frame, "clock": build_clock, "speaker": build_speaker,
    "camera": build_camera, "stapler": build_stapler, "spray": build_spray, "plant": build_plant, "carton": build_carton,
    "backpack": build_backpack, "mouse": build_mouse, "wineglass": build_wineglass,
}
