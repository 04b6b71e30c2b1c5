"""Export a settled simulated scene to USD (usd-core) so it can be opened in any USD viewer.

Every object becomes an Xform (its settled pose) with one Mesh per drawn part, a displayColor, a
semantic label (UsdSemantics.LabelsAPI when available, plus `refspatial:*` custom attributes), and the
furniture becomes static box meshes; cameras of the frames are written as UsdGeom.Camera prims.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from refspatial_gen.core.model import Frame
from refspatial_gen.sources.sim.layout import SceneDesc
from refspatial_gen.sources.sim.physics import SimModel, body_pose


def _name(s: str) -> str:
    n = re.sub(r"[^A-Za-z0-9_]", "_", s)
    return n if n and not n[0].isdigit() else "_" + n


def _mesh(stage, path: str, tm, rgb) -> None:
    from pxr import Gf, UsdGeom, Vt

    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, v)) for v in tm.vertices]))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(tm.faces)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in np.asarray(tm.faces).ravel()]))
    m.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, rgb))]))
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)


def _xform(stage, path: str, R: np.ndarray, p: np.ndarray):
    from pxr import Gf, UsdGeom

    x = UsdGeom.Xform.Define(stage, path)
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, p
    x.AddTransformOp().Set(Gf.Matrix4d(*M.T.ravel().tolist()))  # USD: row vectors
    return x


def export_usd(desc: SceneDesc, sim: SimModel, frames: list[Frame], path: str | Path, colors: dict) -> Path:
    """Write the scene (objects at their settled poses, furniture, cameras) to `path` (.usda or .usdc)."""
    import trimesh
    from pxr import Sdf, Usd, UsdGeom

    path = Path(path)
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Scene")
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.Xform.Define(stage, "/Scene/Room")
    floor = trimesh.creation.box(extents=[2 * desc.room_half[0], 2 * desc.room_half[1], 0.01])
    floor.apply_translation([0, 0, -0.005])
    _mesh(stage, "/Scene/Room/floor", floor, (0.6, 0.55, 0.5))
    for sb in desc.statics:
        b = trimesh.creation.box(extents=2 * sb.half)
        b.apply_translation(sb.center)
        _mesh(
            stage,
            f"/Scene/Room/{_name(sb.name)}",
            b,
            (0.55, 0.4, 0.28) if sb.look in ("table", "shelf") else (0.8, 0.8, 0.8),
        )
    UsdGeom.Xform.Define(stage, "/Scene/Objects")
    try:
        from pxr import UsdSemantics
    except ImportError:  # older usd-core: custom attributes only
        UsdSemantics = None
    for k, o in enumerate(desc.objects):
        p, R = body_pose(sim, k)
        xp = f"/Scene/Objects/{_name(o.key + '_' + o.category.label)}"
        x = _xform(stage, xp, R, p)
        prim = x.GetPrim()
        prim.CreateAttribute("refspatial:category", Sdf.ValueTypeNames.String).Set(o.category.label)
        prim.CreateAttribute("refspatial:instance_id", Sdf.ValueTypeNames.Int).Set(k + 1)
        prim.CreateAttribute("refspatial:color", Sdf.ValueTypeNames.String).Set(o.color)
        prim.CreateAttribute("refspatial:material", Sdf.ValueTypeNames.String).Set(o.material)
        if o.category.front is not None:
            prim.CreateAttribute("refspatial:front", Sdf.ValueTypeNames.Float3).Set(tuple(map(float, o.category.front)))
            prim.CreateAttribute("refspatial:front_phrase", Sdf.ValueTypeNames.String).Set(o.category.front_phrase)
        if UsdSemantics is not None:
            labels = UsdSemantics.LabelsAPI.Apply(prim, "class")
            labels.CreateLabelsAttr([o.category.label])
        for j, part in enumerate(p_ for p_ in o.geometry.parts if p_.visual):
            rgb = (
                o.rgb
                if part.role == "body"
                else o.accent_rgb
                if part.role == "accent"
                else colors.get(part.role, (0.5, 0.5, 0.5))
            )
            _mesh(stage, f"{xp}/part{j}", part.trimesh(), rgb)
    UsdGeom.Xform.Define(stage, "/Scene/Cameras")
    for f in frames:
        cam = f.camera
        R = cam.world_from_cam[:3, :3] @ np.diag([1.0, -1.0, -1.0])  # USD cameras look down -z with y up
        x = _xform(stage, f"/Scene/Cameras/{_name(f.frame_id.split('/')[-1])}", R, cam.world_from_cam[:3, 3])
        c = UsdGeom.Camera.Define(stage, x.GetPath().AppendChild("camera"))
        pix = 0.01  # mm per pixel on a virtual sensor
        c.CreateFocalLengthAttr(float(cam.fy * pix))
        c.CreateHorizontalApertureAttr(float(cam.width * pix))
        c.CreateVerticalApertureAttr(float(cam.height * pix))
        c.CreateClippingRangeAttr((0.01, 100.0))
    stage.GetRootLayer().Save()
    return path
