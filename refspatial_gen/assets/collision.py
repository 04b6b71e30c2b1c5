"""Collision geometry for imported meshes: CoACD convex decomposition, cached by mesh hash.

Why: MuJoCo collides a mesh as its convex hull, so a cup would be a solid cylinder. A decomposition takes
seconds to minutes, so it is made once at import time (never at run time) and kept in the asset cache
(`cache:collision/<hash>/part*.stl`, see paths.py) keyed by the mesh's vertices, faces and the CoACD
parameters; importing the same mesh again costs nothing. A mesh that is already nearly convex keeps its
hull. Parts are in the mesh file's own axes and units, so the catalog's up axis and scale apply to them
exactly as to the drawn mesh.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import trimesh

PARAMS = {"threshold": 0.08, "max_convex_hull": 24, "resolution": 1000, "mcts_iterations": 60, "seed": 0}
CONVEX_ENOUGH = 0.92  # volume / hull volume above this: the hull is a good collision shape


def mesh_hash(mesh: trimesh.Trimesh, params: dict | None = None) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, "<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, "<i8").tobytes())
    h.update(json.dumps(params or PARAMS, sort_keys=True).encode())
    return h.hexdigest()[:24]


def nearly_convex(mesh: trimesh.Trimesh, tol: float = 0.045) -> bool:
    """Whether the convex hull is a good collision shape: 90% of its surface lies within `tol` x the mesh
    size of the mesh (a box, a can with a recessed lid; not a mug's handle hole), measured at 300
    deterministic hull samples. Works on open scanned meshes, where a volume ratio is undefined."""
    try:
        hull = mesh.convex_hull
    except Exception:  # noqa: BLE001 - qhull on degenerate input
        return False
    pts, _ = trimesh.sample.sample_surface_even(hull, 300, seed=0)
    _, dist, _ = trimesh.proximity.closest_point(mesh, pts)
    return bool(np.quantile(dist, 0.9) < tol * float(np.ptp(mesh.vertices, axis=0).max()))


def decompose(mesh: trimesh.Trimesh, cache: Path) -> tuple[str, Path | None]:
    """("hull", None) for nearly convex meshes, else ("parts", folder of part*.stl) from the cache or CoACD."""
    if nearly_convex(mesh):
        return "hull", None
    folder = cache / "collision" / mesh_hash(mesh)
    if (folder / "DONE").exists():
        return "parts", folder
    try:
        import coacd
    except ImportError as e:
        raise ValueError(
            "convex decomposition needs CoACD: pip install 'refspatial-gen[assets]' "
            "(or `make assets-shared`), or import with --collision hull"
        ) from e

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, int)), **PARAMS)
    tmp = folder.with_name(folder.name + f".tmp{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for i, (v, f) in enumerate(parts):
        trimesh.Trimesh(np.asarray(v), np.asarray(f), process=False).export(tmp / f"part{i:03d}.stl")
    (tmp / "DONE").write_text(json.dumps({"parts": len(parts), "params": PARAMS}))
    if folder.exists():  # another process finished first: keep theirs
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        os.replace(tmp, folder)
    return "parts", folder
