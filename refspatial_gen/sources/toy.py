"""A dependency-free "box world" source: coloured boxes on a table, ray-cast in numpy.

Why it exists: graph, QA, shard and run tests need real Frames (consistent RGB, depth, masks, boxes,
camera) in milliseconds and without MuJoCo. It is also the source of the cached-graph QA benchmark.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import Frame, ObjectInstance, SupportSurface

COLOURS = {
    "red": (200, 40, 40),
    "green": (40, 160, 60),
    "blue": (40, 70, 200),
    "yellow": (220, 200, 40),
    "white": (230, 230, 230),
    "black": (30, 30, 30),
    "orange": (235, 130, 30),
    "purple": (130, 60, 170),
}
CATEGORIES = {  # name: (size ranges x, y, z in metres)
    "box": ((0.06, 0.14), (0.06, 0.14), (0.04, 0.12)),
    "book": ((0.14, 0.22), (0.10, 0.16), (0.02, 0.05)),
    "can": ((0.06, 0.07), (0.06, 0.07), (0.10, 0.13)),
    "block": ((0.04, 0.06), (0.04, 0.06), (0.04, 0.06)),
    "tray": ((0.20, 0.30), (0.14, 0.20), (0.02, 0.03)),
}
TABLE = Box3D(np.array([0.0, 0.0, 0.375]), np.array([1.2, 0.8, 0.75]), np.eye(3))


def raycast_boxes(cam: Camera, boxes: list[Box3D]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-pixel nearest hit of camera rays with solid boxes.

    Returns (depth z (H,W), index (H,W) with -1 = none, normal (H,W,3))."""
    H, W = cam.height, cam.width
    vs, us = np.mgrid[0:H, 0:W]
    d_cam = np.stack([(us + 0.5 - cam.cx) / cam.fx, (vs + 0.5 - cam.cy) / cam.fy, np.ones_like(us, float)], -1).reshape(
        -1, 3
    )
    R, o = cam.world_from_cam[:3, :3], cam.world_from_cam[:3, 3]
    d_world = d_cam @ R.T
    best_t = np.full(d_world.shape[0], np.inf)
    best_i = np.full(d_world.shape[0], -1)
    best_n = np.zeros_like(d_world)
    for i, b in enumerate(boxes):
        ol = (o - b.center) @ b.rotation
        dl = d_world @ b.rotation
        half = b.size / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-half - ol) / dl
            t2 = (half - ol) / dl
        tmin = np.minimum(t1, t2)
        tmax = np.maximum(t1, t2)
        tn = np.nanmax(tmin, axis=1)
        tf = np.nanmin(tmax, axis=1)
        hit = (tn <= tf) & (tn > 1e-6) & (tn < best_t)
        axis = np.nanargmax(tmin, axis=1)
        best_t = np.where(hit, tn, best_t)
        best_i = np.where(hit, i, best_i)
        nl = np.zeros_like(dl)
        nl[np.arange(len(dl)), axis] = -np.sign(dl[np.arange(len(dl)), axis])
        best_n = np.where(hit[:, None], nl @ b.rotation.T, best_n)
    depth = np.where(np.isfinite(best_t), best_t, 0.0)  # ray z component in camera frame is 1
    return depth.reshape(H, W).astype(np.float32), best_i.reshape(H, W), best_n.reshape(H, W, 3)


def toy_frame(
    rng: np.random.Generator,
    n_objects: int = 6,
    width: int = 320,
    height: int = 240,
    frame_id: str = "toy",
    boxes: list[tuple[str, str, Box3D]] | None = None,
    camera: Camera | None = None,
) -> Frame:
    """A random (or given) set of boxes on a table seen from a downward-looking camera."""
    top = TABLE.top_z
    if boxes is None:
        boxes = []
        tries = 0
        while len(boxes) < n_objects and tries < 500:
            tries += 1
            cat = str(rng.choice(sorted(CATEGORIES)))
            size = np.array([rng.uniform(*r) for r in CATEGORIES[cat]])
            c = np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.25, 0.25), top + size[2] / 2])
            b = Box3D(c, size, rot_z(rng.uniform(-np.pi, np.pi)))
            if any(
                np.linalg.norm(b.center[:2] - o.center[:2])
                < (np.linalg.norm(b.size[:2]) + np.linalg.norm(o.size[:2])) / 2 + 0.01
                for _, _, o in boxes
            ):
                continue
            boxes.append((cat, str(rng.choice(sorted(COLOURS))), b))
    if camera is None:
        pitch = np.deg2rad(rng.uniform(35, 55))
        yaw = rng.uniform(-0.3, 0.3)
        dist = rng.uniform(0.9, 1.2)
        target = np.array([0.0, 0.0, top])
        eye = target + dist * np.array([np.sin(yaw) * np.cos(pitch), -np.cos(yaw) * np.cos(pitch), np.sin(pitch)])
        f = width / (2 * np.tan(np.deg2rad(60) / 2))
        camera = Camera(width, height, f, f, width / 2, height / 2, look_at(eye, target))
    all_boxes = [TABLE] + [b for _, _, b in boxes]
    depth, idx, normal = raycast_boxes(camera, all_boxes)
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    shade = 0.45 + 0.55 * np.clip(normal @ light, 0, 1)
    rgb = np.zeros((camera.height, camera.width, 3), np.float64) + np.array([90, 110, 130])
    rgb[idx == 0] = np.array([150, 110, 75])
    objects = []
    for k, (cat, colour, b) in enumerate(boxes):
        m = idx == k + 1
        rgb[m] = np.array(COLOURS[colour])
        if not m.any():
            continue
        ys, xs = np.nonzero(m)
        objects.append(
            ObjectInstance(
                id=k + 1,
                category=cat,
                box=b,
                mask=RLE.encode(m),
                bbox2d=(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1)),
                visible_fraction=1.0,
                attributes={"color": colour},
                front=np.array([1.0, 0.0, 0.0]),
                front_phrase="the front",
                provenance={"source": "toy"},
            )
        )
    rgb = np.clip(rgb * np.where(idx >= 0, shade, 1.0)[..., None], 0, 255).astype(np.uint8)
    surfaces = [SupportSurface("table", "table", TABLE, None, "the table")]
    return Frame(frame_id, rgb, depth, camera, objects, surfaces, source="toy", scene_id=frame_id)


class ToySource:
    name = "toy"

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        return [f"toy:{i:06d}" for i in range(scenes if scenes is not None else int(config.get("scenes", 10)))]

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        n = int(rng.integers(config.get("min_objects", 4), config.get("max_objects", 8) + 1))
        return [toy_frame(rng, n, config.get("width", 320), config.get("height", 240), frame_id=unit_key)]
