"""Headless rendering of RGB, metric z-depth and per-geom segmentation with one GL context per process.

Why not `mujoco.Renderer`: it creates a GL context per model, and every scene is a new model. We keep
one EGL context alive for the process and make only a per-model `MjrContext` (uploading that scene's
meshes and textures). RGB and depth come from one pass; segmentation from a second pass with MuJoCo's
id colours.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.sources.sim.physics import HIDDEN_GROUP, SimModel

_GL: dict[str, object] = {}


def _gl_context(width: int, height: int):
    """The process-wide GL context (EGL unless MUJOCO_GL says otherwise), grown when a bigger image is asked."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    from mujoco.rendering.classic import gl_context

    cur = _GL.get("ctx")
    if cur is None or _GL["size"][0] < width or _GL["size"][1] < height:
        if cur is not None:
            cur.free()
        ctx = gl_context.GLContext(max(width, 640), max(height, 480))
        _GL["ctx"], _GL["size"] = ctx, (max(width, 640), max(height, 480))
    ctx = _GL["ctx"]
    ctx.make_current()
    return ctx


@dataclass
class RenderOut:
    rgb: np.ndarray  # uint8 HxWx3
    depth: np.ndarray  # float32 HxW metres (z-depth), 0 = nothing
    instance: np.ndarray  # int32 HxW: object index + 1, 0 = furniture/room/background


def set_camera(sim: SimModel, view: int, cam: Camera) -> None:
    """Put MuJoCo camera `view` at `cam`'s pose (OpenCV axes -> MuJoCo's -z forward, y up) and fovy."""
    from refspatial_gen.assets.shapes import quat_from_matrix

    R_cv = cam.world_from_cam[:3, :3]
    R_mj = R_cv @ np.diag([1.0, -1.0, -1.0])
    sim.model.cam_pos[view] = cam.world_from_cam[:3, 3]
    sim.model.cam_quat[view] = quat_from_matrix(R_mj)
    sim.model.cam_fovy[view] = float(np.rad2deg(2 * np.arctan(cam.height / 2 / cam.fy)))


def render_views(sim: SimModel, cams: list[Camera]) -> list[RenderOut]:
    """Render every camera of the settled scene."""
    import mujoco

    if not cams:
        return []
    W, H = cams[0].width, cams[0].height
    _gl_context(W, H)
    m, d = sim.model, sim.data
    for v, cam in enumerate(cams):
        set_camera(sim, v, cam)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_camlight(m, d)
    near, far = 0.01, 60.0
    m.vis.map.znear = near / m.stat.extent
    m.vis.map.zfar = far / m.stat.extent
    ctx = mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_100.value)
    try:
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, ctx)
        ctx.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        scn = mujoco.MjvScene(m, maxgeom=max(1000, 2 * m.ngeom))
        opt = mujoco.MjvOption()
        opt.geomgroup[HIDDEN_GROUP] = 0
        rect = mujoco.MjrRect(0, 0, W, H)
        outs = []
        zfar, znear = np.float32(m.vis.map.zfar * m.stat.extent), np.float32(m.vis.map.znear * m.stat.extent)
        c_coef = -(zfar + znear) / (zfar - znear)
        d_coef = -(np.float32(2) * zfar * znear) / (zfar - znear)
        c_coef = np.float32(-0.5) * c_coef - np.float32(0.5)
        d_coef = np.float32(-0.5) * d_coef
        for v in range(len(cams)):
            mcam = mujoco.MjvCamera()
            mcam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            mcam.fixedcamid = v
            mujoco.mjv_updateScene(m, d, opt, None, mcam, mujoco.mjtCatBit.mjCAT_ALL.value, scn)
            rgb = np.empty((H, W, 3), np.uint8)
            zbuf = np.empty((H, W), np.float32)
            mujoco.mjr_render(rect, scn, ctx)
            mujoco.mjr_readPixels(rgb, zbuf, rect, ctx)
            z64 = zbuf.astype(np.float64)
            with np.errstate(divide="ignore"):
                depth = d_coef / (z64 + c_coef)
            depth[(zbuf <= 0) | ~np.isfinite(depth) | (depth >= far * 0.999)] = 0.0
            # segmentation pass
            scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = True
            scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = True
            seg = np.empty((H, W, 3), np.uint8)
            mujoco.mjr_render(rect, scn, ctx)
            mujoco.mjr_readPixels(seg, None, rect, ctx)
            scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = False
            scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = False
            segid = (
                seg[..., 0].astype(np.int32) + seg[..., 1].astype(np.int32) * 256 + seg[..., 2].astype(np.int32) * 65536
            )
            lut = np.zeros(scn.ngeom + 2, np.int32)
            for k in range(scn.ngeom):
                g = scn.geoms[k]
                if g.segid >= 0 and g.objtype == mujoco.mjtObj.mjOBJ_GEOM:
                    lut[g.segid + 1] = sim.geom_object[g.objid]
            inst = lut[np.clip(segid, 0, len(lut) - 1)]
            outs.append(
                RenderOut(
                    np.ascontiguousarray(rgb[::-1]),
                    np.ascontiguousarray(depth[::-1].astype(np.float32)),
                    np.ascontiguousarray(inst[::-1]),
                )
            )
        return outs
    finally:
        ctx.free()


class MujocoRenderer:
    """The fast path: MuJoCo's rasteriser on the settled model (one EGL context per process)."""

    name = "mujoco"

    def __init__(self, config: dict | None = None) -> None:
        pass  # nothing to set: resolution and lights are in the compiled model

    def render(self, scene, cams: list[Camera]) -> list[RenderOut]:
        return render_views(scene.sim, cams)
