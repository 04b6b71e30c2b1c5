"""Random scene layouts: furniture (tables, counters, shelves, floor, walls) and objects placed on them.

Why footprints: placing each object by its convex footprint (shapely polygons) on a rectangular surface,
with a clearance, guarantees no interpenetration before physics; stacking puts an object on a flat top
that contains its footprint; containment drops a small object into a container's cavity. Physics then
only has to let everything come to rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from shapely import affinity
from shapely.geometry import Polygon
from shapely.geometry import box as shp_box

from refspatial_gen.assets import AssetGeometry, Catalog, Category, build_geometry
from refspatial_gen.assets.external import external_available

CONTAINER_BUILDERS = ("open_box", "vessel")  # builders whose geometry has a cavity others can go into
CLEARANCE = 0.012  # metres between footprints on one surface
DROP_GAP = 0.002  # objects start this far above their support


@dataclass
class StaticBox:
    """A fixed box of furniture or room (centre, half extents, appearance key)."""

    name: str
    center: np.ndarray
    half: np.ndarray
    look: str  # "table", "counter", "shelf", "wall", "leg"


@dataclass
class Surface:
    """A rectangular horizontal support (axis-aligned): things are placed on its top at `z`."""

    id: str
    kind: str  # table, counter, shelf, floor
    name: str
    center: np.ndarray  # (x, y) centre
    half: np.ndarray  # (hx, hy)
    z: float
    thickness: float
    max_height: float = 10.0  # free height above the top (shelves)
    fps: list = field(default_factory=list)  # footprints placed on it
    # (cx, cy, hx, hy) of the whole top face when things are placed on a smaller area of it (a bed's mattress:
    # objects keep off the pillow end); the frame's support surface (corners, edges, free space) is the face
    face: tuple[float, float, float, float] | None = None

    def rect(self, margin: float = 0.0) -> Polygon:
        (x, y), (hx, hy) = self.center, self.half
        return shp_box(x - hx + margin, y - hy + margin, x + hx - margin, y + hy - margin)


@dataclass
class PlacedObject:
    """One movable object with its appearance and its start pose (origin = bottom centre)."""

    key: str  # unique per scene: "o03"
    category: Category
    geometry: AssetGeometry
    color: str
    rgb: np.ndarray
    accent_rgb: np.ndarray
    material: str
    pos: np.ndarray
    yaw: float
    support: str  # surface id, "on:<key>" or "in:<key>"
    footprint: Any = None
    top_fps: list = field(default_factory=list)  # footprints of things stacked on it
    finish: dict[str, float] | None = None  # specular/shininess/reflectance drawn for this instance (finish.py)


@dataclass
class SceneDesc:
    kind: str  # "tabletop" | "room"
    objects: list[PlacedObject]
    statics: list[StaticBox]
    surfaces: list[Surface]
    focus: list[str]  # surface ids the cameras aim at
    room_half: np.ndarray  # (hx, hy) of the floor area
    walls: bool
    appearance: dict[str, Any]
    floor: bool = True  # False for single-object renders (asset sheets, texture checks)
    lights: list = field(default_factory=list)  # lighting.Light, sampled after the layout


def _outline(geo: AssetGeometry) -> np.ndarray:
    """The 2D convex outline (object frame xy) of the geometry, computed once per instance."""
    if getattr(geo, "_outline", None) is None:
        import cv2

        xy = geo.hull_points()[:, :2].astype(np.float32)
        geo._outline = cv2.convexHull(xy)[:, 0, :].astype(float)
    return geo._outline


def footprint(geo: AssetGeometry, yaw: float) -> Polygon:
    c, s = np.cos(yaw), np.sin(yaw)
    return Polygon(_outline(geo) @ np.array([[c, s], [-s, c]]))


def _jitter_rgb(rgb, rng: np.random.Generator, amount: float = 0.06) -> np.ndarray:
    return np.clip(np.asarray(rgb) * (1 + rng.uniform(-amount, amount, 3)), 0, 1)


class LayoutBuilder:
    """Collects furniture and objects for one scene, drawing everything from one Generator."""

    def __init__(self, catalog: Catalog, rng: np.random.Generator, cfg: dict[str, Any]):
        self.cat, self.rng, self.cfg = catalog, rng, cfg
        self.objects: list[PlacedObject] = []
        self.statics: list[StaticBox] = []
        self.surfaces: list[Surface] = []
        ext_ok = [n for n in catalog.external_names() if external_available(catalog.categories[n])]
        self.external = ext_ok if (cfg.get("external_prob") or 0.0) > 0 else []

    # ------------------------------------------------------------------ furniture
    def add_table(
        self,
        sid: str,
        kind: str,
        name: str,
        cx: float,
        cy: float,
        hx: float,
        hy: float,
        h: float,
        legs: bool = True,
        max_height: float = 10.0,
        look: str | None = None,
    ) -> Surface:
        t = 0.03 if kind != "shelf" else 0.02
        self.statics.append(
            StaticBox(f"{sid}_top", np.array([cx, cy, h - t / 2]), np.array([hx, hy, t / 2]), look or kind)
        )
        if legs:
            for sx in (-1, 1):
                for sy in (-1, 1):
                    self.statics.append(
                        StaticBox(
                            f"{sid}_leg{sx}{sy}",
                            np.array([cx + sx * (hx - 0.05), cy + sy * (hy - 0.05), (h - t) / 2]),
                            np.array([0.025, 0.025, (h - t) / 2]),
                            "leg",
                        )
                    )
        s = Surface(sid, kind, name, np.array([cx, cy]), np.array([hx, hy]), h, t, max_height)
        self.surfaces.append(s)
        return s

    # ------------------------------------------------------------------ objects
    def pick_category(self, scale: str, want_inside: bool = False) -> Category:
        rng = self.rng
        if (
            self.external
            and scale == "tabletop"
            and not want_inside
            and rng.random() < (self.cfg.get("external_prob") or 0.0)
        ):
            return self.cat.categories[self.external[int(rng.integers(len(self.external)))]]
        same = [
            o.category
            for o in self.objects
            if o.category.scale == scale
            and o.category.builder != "external"
            and (o.category.fits_inside or not want_inside)
        ]
        if same and rng.random() < self.cfg.get("repeat_prob", 0.3):
            return same[int(rng.integers(len(same)))]
        names = [
            n
            for n in self.cat.names(scale)
            if self.cat.categories[n].builder != "external" and (self.cat.categories[n].fits_inside or not want_inside)
        ]
        w = np.array([self.cat.categories[n].weight for n in names])
        return self.cat.categories[names[int(rng.choice(len(names), p=w / w.sum()))]]

    def make(self, cat: Category) -> tuple[AssetGeometry, str, np.ndarray, np.ndarray, str]:
        rng = self.rng
        geo = build_geometry(cat, cat.sample_dims(rng), rng)
        used = {o.color for o in self.objects if o.category.name == cat.name}
        fresh = [c for c in cat.colors if c not in used] or list(cat.colors)
        color = fresh[int(rng.integers(len(fresh)))]
        acc_names = list(cat.accent) or ["black", "white", "gray"]
        accent = acc_names[int(rng.integers(len(acc_names)))]
        mat = cat.materials[int(rng.integers(len(cat.materials)))]
        return geo, color, _jitter_rgb(self.cat.colors[color], rng), _jitter_rgb(self.cat.colors[accent], rng), mat

    def _yaw_for(self, cat: Category, xy: np.ndarray) -> float:
        """Random yaw; objects with a front sometimes face another object exactly (facing relations)."""
        rng = self.rng
        others = self.objects
        if cat.front is not None and others and rng.random() < self.cfg.get("face_prob", 0.35):
            t = others[int(rng.integers(len(others)))].pos[:2]
            ang = np.arctan2(t[1] - xy[1], t[0] - xy[0]) - np.arctan2(cat.front[1], cat.front[0])
            return float(ang + rng.normal(0, 0.08))
        return float(rng.uniform(-np.pi, np.pi))

    def _add(self, cat, geo, color, rgb, acc, mat, pos, yaw, support, fp) -> PlacedObject:
        o = PlacedObject(
            f"o{len(self.objects):02d}", cat, geo, color, rgb, acc, mat, np.asarray(pos, float), yaw, support, fp
        )
        self.objects.append(o)
        return o

    def place_on_surface(self, surf: Surface, cat: Category, tries: int = 30) -> PlacedObject | None:
        rng = self.rng
        geo, color, rgb, acc, mat = self.make(cat)
        lo, hi = geo.bounds()
        if hi[2] - lo[2] > surf.max_height - 0.02:
            return None
        edge_p = self.cfg.get("edge_prob", 0.3)
        rect = surf.rect(0.01)
        for _ in range(tries):
            r = rng.random()
            if r < edge_p:  # near an edge or a corner: the border band of the surface
                band = 0.12
                u = rng.uniform(-1, 1, 2)
                side = int(rng.integers(2))
                u[side] = np.sign(u[side] + 1e-9) * rng.uniform(1 - band / max(surf.half[side], band), 1)
                if rng.random() < 0.4:  # corner
                    u[1 - side] = np.sign(u[1 - side] + 1e-9) * rng.uniform(
                        1 - band / max(surf.half[1 - side], band), 1
                    )
                xy = surf.center + u * surf.half
            else:
                xy = surf.center + rng.uniform(-1, 1, 2) * surf.half
            yaw = self._yaw_for(cat, xy)
            fp = affinity.translate(footprint(geo, yaw), xy[0], xy[1])
            if not rect.contains(fp):
                # pull it inwards just enough: try the nearest position that fits
                minx, miny, maxx, maxy = fp.bounds
                rx0, ry0, rx1, ry1 = rect.bounds
                dx = max(0.0, rx0 - minx) - max(0.0, maxx - rx1)
                dy = max(0.0, ry0 - miny) - max(0.0, maxy - ry1)
                fp = affinity.translate(fp, dx, dy)
                xy = xy + np.array([dx, dy])
                if not rect.contains(fp):
                    continue
            if any(fp.distance(o) < CLEARANCE for o in surf.fps):
                continue
            surf.fps.append(fp)
            pos = np.array([xy[0], xy[1], surf.z - lo[2] + DROP_GAP])
            return self._add(cat, geo, color, rgb, acc, mat, pos, yaw, surf.id, fp)
        return None

    def stack_on(self, base: PlacedObject, cat: Category, tries: int = 15) -> PlacedObject | None:
        rng = self.rng
        geo, color, rgb, acc, mat = self.make(cat)
        lo, hi = geo.bounds()
        blo, bhi = base.geometry.bounds()
        top = base.footprint.buffer(-0.005)
        for _ in range(tries):
            yaw = float(rng.uniform(-np.pi, np.pi))
            fp0 = footprint(geo, yaw)
            c = np.array(base.footprint.centroid.coords[0]) + rng.normal(0, 0.02, 2)
            fp = affinity.translate(fp0, c[0], c[1])
            if fp.area > top.area * 0.9 or not top.contains(fp.centroid) or fp.difference(top).area > 0.15 * fp.area:
                continue
            if any(fp.distance(o) < CLEARANCE for o in base.top_fps):
                continue
            base.top_fps.append(fp)
            z = base.pos[2] + bhi[2] - lo[2] + DROP_GAP
            return self._add(cat, geo, color, rgb, acc, mat, np.array([c[0], c[1], z]), yaw, f"on:{base.key}", fp)
        return None

    def put_inside(self, box: PlacedObject, cat: Category, tries: int = 15) -> PlacedObject | None:
        rng = self.rng
        geo, color, rgb, acc, mat = self.make(cat)
        lo, hi = geo.bounds()
        cc, cs = box.geometry.cavity
        cav = affinity.rotate(
            shp_box(-cs[0] / 2 + 0.004, -cs[1] / 2 + 0.004, cs[0] / 2 - 0.004, cs[1] / 2 - 0.004),
            box.yaw,
            origin=(0, 0),
            use_radians=True,
        )
        cav = affinity.translate(cav, box.pos[0] + cc[0], box.pos[1] + cc[1])
        for _ in range(tries):
            yaw = float(rng.uniform(-np.pi, np.pi))
            c = np.array(cav.centroid.coords[0]) + rng.normal(0, 0.01, 2)
            fp = affinity.translate(footprint(geo, yaw), c[0], c[1])
            if not cav.contains(fp) or any(fp.distance(o) < 0.004 for o in box.top_fps):
                continue
            box.top_fps.append(fp)
            z = box.pos[2] - box.geometry.bounds()[0][2] + cc[2] - cs[2] / 2 - lo[2] + DROP_GAP
            return self._add(cat, geo, color, rgb, acc, mat, np.array([c[0], c[1], z]), yaw, f"in:{box.key}", fp)
        return None

    def fill(self, surfaces: list[Surface], n: int, scale: str = "tabletop") -> None:
        """Place `n` objects on the given surfaces (tables weigh 3x shelves and counters), stacking and
        filling containers now and then."""
        rng = self.rng
        sw = np.array([3.0 if s.kind == "table" else 1.0 for s in surfaces])
        stack_p, inside_p = self.cfg.get("stack_prob", 0.25), self.cfg.get("inside_prob", 0.3)
        placed, attempts = 0, 0
        while placed < n and attempts < 4 * n + 10:
            attempts += 1
            mine = [o for o in self.objects if o.support in {s.id for s in surfaces}]
            containers = [
                o
                for o in mine
                if o.geometry.cavity is not None and len(o.top_fps) < 2 and min(o.geometry.cavity[1][:2]) > 0.075
            ]
            flats = [o for o in mine if o.geometry.flat_top and len(o.top_fps) < 2]
            r = rng.random()
            obj = None
            if containers and r < inside_p:
                box = containers[int(rng.integers(len(containers)))]
                for _ in range(3):  # a few categories: not every small thing fits every container
                    obj = self.put_inside(box, self.pick_category(scale, want_inside=True))
                    if obj is not None:
                        break
            elif r < inside_p and scale == "tabletop":  # no container yet: bring one, to be filled next
                boxes = [n for n in self.cat.names(scale) if self.cat.categories[n].builder in CONTAINER_BUILDERS]
                if boxes:
                    cat = self.cat.categories[boxes[int(rng.integers(len(boxes)))]]
                    obj = self.place_on_surface(surfaces[int(rng.choice(len(surfaces), p=sw / sw.sum()))], cat)
            elif flats and r < inside_p + stack_p:
                obj = self.stack_on(flats[int(rng.integers(len(flats)))], self.pick_category(scale))
            else:
                obj = self.place_on_surface(
                    surfaces[int(rng.choice(len(surfaces), p=sw / sw.sum()))], self.pick_category(scale)
                )
            placed += obj is not None


TABLE_TINTS = [
    (1.0, 0.85, 0.7),
    (0.75, 0.55, 0.4),
    (0.55, 0.38, 0.25),
    (0.95, 0.95, 0.95),
    (0.35, 0.35, 0.37),
    (0.9, 0.8, 0.65),
]
FABRICS = [
    (0.45, 0.5, 0.58),
    (0.6, 0.55, 0.48),
    (0.35, 0.4, 0.33),
    (0.55, 0.25, 0.22),
    (0.3, 0.3, 0.32),
    (0.75, 0.72, 0.66),
]


def _pick(rng: np.random.Generator, options: list) -> np.ndarray:
    return np.array(options[int(rng.integers(len(options)))], float)


def appearance(rng: np.random.Generator) -> dict[str, Any]:
    """Random looks of the room and furniture (lights are sampled separately, see lighting.py)."""
    tint = _pick(rng, TABLE_TINTS) * rng.uniform(0.9, 1.1)
    return {
        "table_tex": int(rng.integers(4)),
        "table_tint": np.clip(tint, 0, 1),
        "floor_tex": int(rng.integers(3)),
        "floor_rgb1": rng.uniform(0.35, 0.8) * _pick(rng, TABLE_TINTS),
        "wall_rgb": rng.uniform(0.65, 0.95, 3),
        "counter_rgb": _pick(rng, TABLE_TINTS) * rng.uniform(0.6, 1.0),
        "cabinet_rgb": np.clip(_pick(rng, TABLE_TINTS) * rng.uniform(0.7, 1.05), 0, 1),
        "sofa_rgb": _pick(rng, FABRICS) * rng.uniform(0.85, 1.1),
        "bedding_rgb": np.clip(rng.uniform(0.75, 1.0, 3), 0, 1),
        "ambient": float(rng.uniform(0.2, 0.35)),
        "headlight": 0.15,
    }
