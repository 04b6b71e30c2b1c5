"""Procedural object geometry: the parts (visual meshes and convex collision pieces) objects are built from.

Why convex pieces: MuJoCo collides every mesh as its convex hull, so a cup given as one mesh is a solid
cylinder and nothing can go inside it. Building concave shapes (cups, bowls, open boxes, trays) from
boxes and cylinders is deterministic, costs nothing at run time (no decomposition, no cache) and lets
objects rest inside containers. The per-category builders are in shapes_containers.py and
shapes_objects.py; `shapes.BUILDERS` names them.

Object frame: origin at the bottom centre, z up, +x is the side a category's semantic front refers to
(e.g. the mug handle), metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

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
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


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
            scale = {
                "box": lambda z: np.asarray(z[:3]),
                "cylinder": lambda z: np.array([z[0], z[0], z[1]]),
                "sphere": lambda z: np.array([z[0]] * 3),
                "ellipsoid": lambda z: np.asarray(z[:3]),
            }
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


def mesh_part(m: trimesh.Trimesh, role: str = "body", collide: bool = True, visual: bool = True) -> Part:
    return Part("mesh", (), np.zeros(3), np.eye(3), m, role, visual, collide)


def revolve(profile: list[tuple[float, float]], sections: int = 28) -> trimesh.Trimesh:
    """Revolve an (r, z) polyline about z. A closed profile that starts and ends on the axis gives a
    watertight solid; give it counter-clockwise in the (r, z) plane."""
    return trimesh.creation.revolve(np.asarray(profile, float), sections=sections)


def box_part(center, half, role="body", rot=None, visual=True, collide=True) -> Part:
    return Part(
        "box",
        tuple(float(h) for h in half),
        np.asarray(center, float),
        np.eye(3) if rot is None else rot,
        None,
        role,
        visual,
        collide,
    )


def cyl_part(center, r, half_h, role="body", rot=None, visual=True, collide=True) -> Part:
    return Part(
        "cylinder",
        (float(r), float(half_h)),
        np.asarray(center, float),
        np.eye(3) if rot is None else rot,
        None,
        role,
        visual,
        collide,
    )


def wall_ring(r0: float, z0: float, r1: float, z1: float, thick: float, n: int = 12) -> list[Part]:
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
        parts.append(box_part(c, (thick / 2, half_w, seg / 2), rot=R, visual=False))
    return parts


def open_vessel(
    r_bot: float, r_top: float, h: float, wall: float, bottom: float, curve: float = 0.0, sections: int = 28
) -> tuple[list[Part], tuple[np.ndarray, np.ndarray]]:
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
    parts = [mesh_part(vis, collide=False)]
    parts.append(cyl_part((0, 0, bottom / 2), r_bot, bottom / 2, visual=False))
    for a, b in zip(outer[:-1], outer[1:]):
        parts += wall_ring(a[0] - wall / 2, a[1], b[0] - wall / 2, b[1], wall, n=12)
    rin = max(r_bot - wall, 0.005)
    cav = (np.array([0, 0, (bottom + h) / 2]), np.array([2 * rin, 2 * rin, h - bottom]))
    return parts, cav
