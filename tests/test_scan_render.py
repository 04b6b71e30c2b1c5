"""Rendered scans: USD stages (labelled prims -> boxes, MuJoCo views) and the COLMAP SfM round trip."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from refspatial_gen.core.camera import look_at
from refspatial_gen.sources import get_source
from refspatial_gen.sources.scan.render import RenderGeom, render, render_camera

OBJECTS = [  # category, centre, size, colour
    ("box", (0.15, 0.05, 0.80), (0.16, 0.12, 0.10), (0.8, 0.2, 0.2, 1)),
    ("book", (-0.25, -0.05, 0.765), (0.22, 0.15, 0.03), (0.2, 0.3, 0.8, 1)),
    ("can", (0.0, 0.22, 0.81), (0.07, 0.07, 0.12), (0.9, 0.8, 0.2, 1)),
]


def write_usd(path: Path) -> None:
    from pxr import Gf, Usd, UsdGeom, UsdSemantics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)

    def cube(name, centre, size, colour, label, yaw=0.0):
        c = UsdGeom.Cube.Define(stage, f"/World/{name}")
        c.GetSizeAttr().Set(1.0)
        c.AddTranslateOp().Set(Gf.Vec3d(*centre))
        c.AddRotateZOp().Set(float(np.degrees(yaw)))
        c.AddScaleOp().Set(Gf.Vec3f(*size))
        c.GetDisplayColorAttr().Set([Gf.Vec3f(*colour[:3])])
        if label:
            UsdSemantics.LabelsAPI.Apply(c.GetPrim(), "class").CreateLabelsAttr().Set([label])

    cube("floor", (0, 0, -0.01), (4, 4, 0.02), (0.5, 0.5, 0.5, 1), None)
    cube("table", (0, 0, 0.375), (1.0, 0.7, 0.75), (0.6, 0.45, 0.3, 1), "table")
    for k, (cat, c, s, col) in enumerate(OBJECTS):
        cube(f"{cat}{k}", c, s, col, cat, yaw=0.3 * k)
    cam = UsdGeom.Camera.Define(stage, "/World/cam_front")
    T = look_at(np.array([0.0, -1.3, 1.4]), np.array([0.0, 0.0, 0.78]))
    M = T.copy()
    M[:3, :3] = T[:3, :3] @ np.diag([1.0, -1.0, -1.0])  # OpenCV -> USD camera axes (-Z forward, +Y up)
    cam.AddTransformOp().Set(Gf.Matrix4d(M.T.tolist()))
    cam.GetFocalLengthAttr().Set(18.0)
    cam.GetVerticalApertureAttr().Set(15.0)
    cam.GetHorizontalApertureAttr().Set(20.0)
    stage.GetRootLayer().Save()


@pytest.mark.slow
def test_usd_stage_boxes_and_rendered_views(tmp_path):
    write_usd(tmp_path / "scene.usda")
    src = get_source("scan")
    cfg = {k: f.default for k, f in src.CONFIG_FIELDS.items()} | {"blur_threshold": 0.0, "min_mask_pixels": 16}
    keys = src.unit_keys(cfg, None, str(tmp_path))
    assert keys == ["scan:usd:.#World.cam_front"]
    (f,) = src.load(keys[0], np.random.default_rng(0), cfg | {"_input": str(tmp_path)})
    assert f.meta["gravity_source"] == "given" and f.camera.gravity_known
    cats = {o.category: o for o in f.objects}
    assert set(cats) == {"table", "box", "book", "can"}
    for k, (cat, c, s, _) in enumerate(OBJECTS):
        o = cats[cat]
        np.testing.assert_allclose(o.box.center, c, atol=1e-6)
        np.testing.assert_allclose(o.box.size, s, atol=1e-6)
        assert abs(o.box.yaw - 0.3 * k) < 1e-6
        # the mask lies on the object's rendered colour
        px = f.rgb[o.mask.decode()].astype(float).mean(axis=0)
        assert np.argmax(px) == int(np.argmax(OBJECTS[k][3][:3])), (cat, px)
    cv2.imwrite("/tmp/scan_usd_preview.png", f.rgb[..., ::-1])


def textured_scene() -> list[RenderGeom]:
    g = [RenderGeom("floor", np.array([0, 0, -0.01]), np.array([3, 3, 0.02]), texture_seed=11),
         RenderGeom("table", np.array([0, 0, 0.375]), np.array([1.2, 0.8, 0.75]), texture_seed=12)]
    for k, (cat, c, s, _) in enumerate(OBJECTS):
        g.append(RenderGeom(f"{cat}{k}", np.array(c), np.array(s), texture_seed=20 + k))
    return g


@pytest.mark.slow
def test_colmap_sfm_round_trip_pose_error(tmp_path):
    """Render 8 views of a textured table, run SfM with pycolmap, align to ground truth, report the error."""
    from refspatial_gen.sources.scan.readers.colmap import model_poses, pose_errors, run_sfm

    proj = tmp_path / "proj"
    (proj / "images").mkdir(parents=True)
    (proj / "depth").mkdir()
    cams, truth = [], {}
    for k in range(8):
        a = -0.9 + 1.8 * k / 7
        eye = np.array([1.4 * np.sin(a), -1.4 * np.cos(a), 1.35 + 0.1 * np.cos(3 * a)])
        cams.append(render_camera(640, 480, 55, look_at(eye, np.array([0.0, 0.0, 0.78]))))
    views = render(textured_scene(), cams)
    for k, (cam, (rgb, depth, _)) in enumerate(zip(cams, views)):
        name = f"view{k:02d}.png"
        cv2.imwrite(str(proj / "images" / name), rgb[..., ::-1])
        cv2.imwrite(str(proj / "depth" / f"view{k:02d}.png"), np.round(depth * 1000).astype(np.uint16))
        truth[name] = cam.world_from_cam
    free = pose_errors(model_poses(run_sfm(proj / "images", tmp_path / "free")), truth)
    c = cams[0]
    rec = run_sfm(proj / "images", proj, camera_params=(c.fx, c.fy, c.cx, c.cy))
    est = model_poses(rec)
    err = pose_errors(est, truth)
    print(f"\nCOLMAP round trip, intrinsics estimated: centre error max {1000 * free['max_centre_err_m']:.2f} mm, "
          f"rotation error max {free['max_rot_err_deg']:.3f} deg")
    print(f"COLMAP round trip, intrinsics known: {len(est)}/8 views registered, reprojection {rec.compute_mean_reprojection_error():.3f} px, "
          f"camera centre error max {1000 * err['max_centre_err_m']:.2f} mm mean {1000 * np.mean(err['centre_err_m']):.2f} mm, "
          f"rotation error max {err['max_rot_err_deg']:.3f} deg")
    assert len(est) == 8
    assert err["max_centre_err_m"] < 0.01 and err["max_rot_err_deg"] < 0.5
    # the aligned model becomes scan frames: boxes given in the simulator's world
    (proj / "reference_poses.json").write_text(json.dumps({k: v.tolist() for k, v in truth.items()}))
    (proj / "boxes.json").write_text(json.dumps({"objects": [
        {"id": k + 1, "category": cat, "center": list(c), "size": list(s), "yaw": 0.0} for k, (cat, c, s, _) in enumerate(OBJECTS)]}))
    src = get_source("scan")
    cfg = {k: f.default for k, f in src.CONFIG_FIELDS.items()} | {"blur_threshold": 0.0, "min_mask_pixels": 16}
    keys = src.unit_keys(cfg, None, str(proj))
    assert len(keys) == 8 and keys[0].startswith("scan:colmap:")
    (f,) = src.load(keys[3], np.random.default_rng(0), cfg | {"_input": str(proj)})
    assert f.meta["gravity_source"] == "given" and f.meta["alignment"]["max_centre_err_m"] < 0.01
    assert {o.category for o in f.objects} == {"box", "book", "can"}
    np.testing.assert_allclose(f.camera.world_from_cam[:3, 3], cams[3].world_from_cam[:3, 3], atol=0.01)
