"""Which object stands on what: a support surface (table top, shelf, floor) or another object.

Why: on/under, stacking, corners, edges and free space all need to know the surface under an object.
Rule (shared/spec/relations.md): a support's top lies within `support_gap` of the object's bottom and
covers at least `support_overlap` of the object's footprint (for an object support, of the smaller of the
two footprints, so a wide book can rest on a small block), and, for an object support, its category can
bear the object's (truth/data/bearing.yaml via `truth.can_bear`: a car or a person carries nothing; a
refusal is counted as `support_cannot_bear` in graph.meta["truth"]). The nearest such top wins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from refspatial_gen.core.geometry import Box3D
from refspatial_gen.graph.scene import SceneGeom, ccw, points_in_polygons
from refspatial_gen.truth.sizes import can_bear


@dataclass(frozen=True)
class Support:
    kind: str  # "surface" | "object"
    ref: str | int  # surface id, or the supporting object's id
    gap: float  # object's bottom minus the support's top (m)
    overlap: float  # share of the footprint supported

    @property
    def label(self) -> str:
        return str(self.ref) if self.kind == "surface" else f"obj:{self.ref}"


def _grid_in(fp: np.ndarray, k: int = 6) -> np.ndarray:
    t = (np.arange(k) + 0.5) / k
    u, v = np.meshgrid(t, t, indexing="ij")
    return fp[0] + u.ravel()[:, None] * (fp[1] - fp[0]) + v.ravel()[:, None] * (fp[3] - fp[0])


def surface_polygon(box: Box3D) -> np.ndarray:
    """CCW xy outline of a surface slab's top face."""
    hx, hy = box.size[0] / 2, box.size[1] / 2
    local = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]])
    return ccw((box.center + local @ box.rotation.T)[:, :2])


def find_supports(geom: SceneGeom) -> list[Support | None]:
    """The support of every object (by position), or None."""
    if not geom.world_ok:
        return [None] * geom.n
    th = geom.th
    surfs = geom.surfaces
    spolys = np.array([surface_polygon(s.box) for s in surfs]).reshape(len(surfs), 4, 2)
    stops = np.array([s.top_z for s in surfs])
    ov = geom.footprint_overlap  # (i, j): share of i over j
    area = geom.footprint_area
    out: list[Support | None] = []
    refused = 0
    copies = np.array([o.provenance.get("distractor_only") == "lookalike" for o in geom.frame.objects], bool)
    shares = np.zeros((geom.n, len(surfs)))
    if len(surfs) and geom.n:  # share of each object's footprint grid over each surface, in one call
        grids = np.stack([_grid_in(fp) for fp in geom.footprints])  # (n, 36, 2)
        inside = points_in_polygons(grids.reshape(-1, 2), spolys).reshape(len(surfs), geom.n, grids.shape[1])
        shares = inside.mean(axis=2).T
    for i in range(geom.n):
        cands = []
        bottom = geom.lo[i, 2]
        if len(surfs):
            share = shares[i]
            for k, s in enumerate(surfs):
                gap = bottom - stops[k]
                if abs(gap) <= th.support_gap and share[k] >= th.support_overlap:
                    cands.append((abs(gap), 1, Support("surface", s.id, float(gap), float(share[k]))))
        near = (np.abs(bottom - geom.hi[:, 2]) <= th.support_gap) & (geom.hi[:, 2] < geom.hi[i, 2])
        near[i] = False
        near &= ~copies  # a look-alike stand-in is a second reading of an object: that object is the support
        for j in np.flatnonzero(near):  # tops within the gap, below i's top
            gap = bottom - geom.hi[j, 2]
            # share of the smaller footprint that the two have in common
            common = ov[i, j] if area[i] <= area[j] else ov[j, i]
            if common >= th.support_overlap and geom.centers[i, 2] > geom.centers[j, 2]:
                if not _bears(geom, int(j), i):
                    refused += 1
                    continue
                cands.append((abs(gap), 0, Support("object", int(geom.ids[j]), float(gap), float(common))))
        # nearest top first; on ties an object beats the surface below it (it is the one touched)
        cands.sort(key=lambda c: (round(c[0], 4), c[1], str(c[2].ref)))
        out.append(cands[0][2] if cands else None)
    if refused:
        truth = geom.cache.setdefault("truth", {})
        truth["support_cannot_bear"] = truth.get("support_cannot_bear", 0) + refused
    return out


def _bears(geom: SceneGeom, j: int, i: int) -> bool:
    """Can object j carry object i on its top (category rule and overhang, gravity-aligned box sizes)?"""
    sj = (float(geom.width[j]), float(geom.width[j]), float(geom.height[j]))
    si = (float(geom.width[i]), float(geom.width[i]), float(geom.height[i]))
    return can_bear(geom.categories[j], geom.categories[i], support_size=sj, object_size=si)


def root_surfaces(geom: SceneGeom, supports: list[Support | None]) -> list[str | None]:
    """The surface at the bottom of each object's support chain (None when it has none)."""
    out = []
    for i in range(geom.n):
        seen, s = set(), supports[i]
        while s is not None and s.kind == "object" and s.ref not in seen:
            seen.add(s.ref)
            s = supports[geom.index[int(s.ref)]]
        out.append(str(s.ref) if s is not None and s.kind == "surface" else None)
    return out


def get_supports(geom: SceneGeom) -> tuple[list[Support | None], list[str | None]]:
    if "supports" not in geom.cache:
        sup = find_supports(geom)
        geom.cache["supports"] = (sup, root_surfaces(geom, sup))
    return geom.cache["supports"]
