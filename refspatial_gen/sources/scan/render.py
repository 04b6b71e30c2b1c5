"""A small MuJoCo renderer for scan-like test scenes and USD stages (RGB, z-depth, per-geom ids).

Why here: USD stages carry geometry but no images, and the COLMAP round trip needs views with known
poses. MuJoCo renders headless with MUJOCO_GL=egl. The camera must be centred (cx = W/2, cy = H/2 in
Camera's corner-origin pixels) with square pixels, which is what `render_camera` builds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera


@dataclass
class RenderGeom:
    """A box (`size` full extents) or a triangle mesh (`vertices` world, `faces`), with a colour or a
    random texture (seed) for feature-rich surfaces."""

    name: str
    center: np.ndarray | None = None
    size: np.ndarray | None = None
    rotation: np.ndarray | None = None
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    rgba: tuple[float, float, float, float] = (0.7, 0.7, 0.7, 1.0)
    texture_seed: int | None = None


def render_camera(width: int, height: int, fovy_deg: float, world_from_cam: np.ndarray) -> Camera:
    f = height / (2 * np.tan(np.deg2rad(fovy_deg) / 2))
    return Camera(width, height, f, f, width / 2, height / 2, world_from_cam, True)


def _mat_to_quat(R: np.ndarray) -> np.ndarray:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=np.float64).ravel())
    return q


def _noise_texture(seed: int, n: int = 256) -> bytes:
    """High-frequency random blobs in colour: matches well under SIFT (checkerboards do not)."""
    import cv2

    rng = np.random.default_rng(seed)
    img = np.zeros((n, n, 3), np.float32)
    for scale in (4, 16, 64):
        small = rng.uniform(0, 255, (scale, scale, 3)).astype(np.float32)
        img += cv2.resize(small, (n, n), interpolation=cv2.INTER_CUBIC) / 3
    return np.clip(img, 0, 255).astype(np.uint8).tobytes()


def render(
    geoms: list[RenderGeom], cams: list[Camera], light_dir=(0.3, -0.4, -1.0)
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Render every camera -> [(rgb uint8, depth float32 metres, geom index int (-1 = background))]."""
    import mujoco

    spec = mujoco.MjSpec()
    spec.visual.global_.offwidth = max(c.width for c in cams)
    spec.visual.global_.offheight = max(c.height for c in cams)
    spec.visual.headlight.ambient = [0.45, 0.45, 0.45]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    wb = spec.worldbody
    for k, g in enumerate(geoms):
        _add_geom(spec, wb, k, g)
    ld = np.asarray(light_dir, float)
    wb.add_light(pos=(-ld * 5).tolist(), dir=ld.tolist(), diffuse=[0.6, 0.6, 0.6], castshadow=False)
    for i, c in enumerate(cams):
        R = c.world_from_cam[:3, :3] @ np.diag([1.0, -1.0, -1.0])
        wb.add_camera(
            name=f"cam{i}",
            pos=c.world_from_cam[:3, 3].tolist(),
            quat=_mat_to_quat(R).tolist(),
            fovy=float(np.degrees(2 * np.arctan(c.height / (2 * c.fy)))),
        )
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom_ids = {model.geom(g.name).id: k for k, g in enumerate(geoms)}
    out = []
    for i, c in enumerate(cams):
        r = mujoco.Renderer(model, c.height, c.width)
        try:
            r.update_scene(data, camera=f"cam{i}")
            rgb = r.render().copy()
            r.enable_depth_rendering()
            depth = r.render().astype(np.float32)
            r.disable_depth_rendering()
            r.enable_segmentation_rendering()
            seg = r.render()[..., 0]
            r.disable_segmentation_rendering()
        finally:
            r.close()
        idx = np.full(seg.shape, -1, int)
        for gid, k in geom_ids.items():
            idx[seg == gid] = k
        depth[idx < 0] = 0.0
        out.append((rgb, depth, idx))
    return out


def _add_geom(spec: Any, wb: Any, k: int, g: RenderGeom) -> None:
    """Geom k: a mesh or a box, with a noise texture when it has a texture seed."""
    import mujoco

    kw = {}
    if g.texture_seed is not None:
        spec.add_texture(
            name=f"tex{k}",
            type=mujoco.mjtTexture.mjTEXTURE_2D,
            width=256,
            height=256,
            nchannel=3,
            data=list(_noise_texture(g.texture_seed)),
        )
        mat = spec.add_material(name=f"mat{k}", texuniform=True, texrepeat=[2, 2])
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"tex{k}"
        kw["material"] = f"mat{k}"
    if g.vertices is not None:
        spec.add_mesh(
            name=f"mesh{k}",
            uservert=np.asarray(g.vertices, float).ravel().tolist(),
            userface=np.asarray(g.faces, int).ravel().tolist(),
        )
        wb.add_geom(
            name=g.name,
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=f"mesh{k}",
            rgba=list(g.rgba),
            contype=0,
            conaffinity=0,
            **kw,
        )
    else:
        wb.add_geom(
            name=g.name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=(np.asarray(g.size) / 2).tolist(),
            pos=np.asarray(g.center, float).tolist(),
            quat=_mat_to_quat(np.eye(3) if g.rotation is None else g.rotation).tolist(),
            rgba=list(g.rgba),
            contype=0,
            conaffinity=0,
            **kw,
        )
