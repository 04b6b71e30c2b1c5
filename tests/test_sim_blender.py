"""The Blender renderer: recipe checks and the MuJoCo/Blender agreement check (fast, no bpy needed), and
real Cycles renders at 96x72 with a few samples (slow; skipped with a reason when bpy is not set up)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.sim.render_check import agreement, disagreement
from refspatial_gen.tools.lint import lint_file

REPO = Path(__file__).resolve().parents[1]
SMALL = {"width": 96, "height": 72, "renderer": "blender", "blender": {"samples": 4}}


def _recipe(tmp_path: Path, config: str) -> Path:
    p = tmp_path / "r.yaml"
    tpl = REPO / "recipes" / "templates" / "locate.yaml"
    p.write_text(
        f"name: t\nsources:\n  - kind: sim\n    config:\n{config}qa:\n  families:\n"
        f"    locate: {{weight: 1.0, templates: ['{tpl}']}}\n"
    )
    return p


def test_blender_section_is_checked_with_lines(tmp_path):
    errs = lint_file(
        _recipe(
            tmp_path,
            "      renderer: mujoco\n      blender:\n        samples: 0\n        device: tpu\n        sample: 3\n",
        )
    )
    msgs = sorted((e.line, e.message) for e in errs)
    assert [ln for ln, _ in msgs] == [7, 8, 9], msgs
    assert "samples must be >= 1" in msgs[0][1] and "device must be one of cpu, cuda, optix, auto" in msgs[1][1]
    assert "unknown key 'sample'" in msgs[2][1]


def test_renderer_blender_without_its_environment_is_a_recipe_error(tmp_path):
    errs = lint_file(
        _recipe(tmp_path, f"      renderer: blender\n      blender: {{python: {tmp_path / 'no' / 'python'}}}\n")
    )
    assert len(errs) == 1 and errs[0].line == 5 and "make setup-blender" in errs[0].message


def test_agreement_counts_shifted_masks_and_wrong_depths():
    ids = np.zeros((40, 60), np.int32)
    ids[10:20, 10:20] = 1  # 100 px
    ids[25:35, 30:50] = 2  # 200 px
    depth = np.full((40, 60), 2.0, np.float32)
    same = agreement(depth, ids, depth.copy(), ids.copy(), min_pixels=10, depth_tol=0.01, depth_rel_tol=0.0)
    assert same == {"objects": 2, "mask_iou_mean": 1.0, "mask_iou_min": 1.0, "worst_id": 1, "depth_agree": 1.0}
    shifted = np.zeros_like(ids)
    shifted[10:20, 12:22] = 1  # 2 columns off: IoU 80 / 120
    shifted[25:35, 30:50] = 2
    far = depth.copy()
    far[:4] = 2.5  # 240 of 2400 pixels 0.5 m off
    st = agreement(depth, ids, far, shifted, min_pixels=10, depth_tol=0.01, depth_rel_tol=0.01)
    assert st["worst_id"] == 1 and st["mask_iou_min"] == round(80 / 120, 4) and st["depth_agree"] == 0.9
    assert "object 1 mask IoU 0.667 < 0.8" == disagreement(st, 0.8, 0.5)
    assert "depth agrees on 0.900 of pixels < 0.95" == disagreement(st, 0.5, 0.95)
    assert disagreement(st, 0.5, 0.9) is None
    tiny = agreement(depth, ids, depth, np.where(ids == 1, 0, ids), min_pixels=101, depth_tol=0.01, depth_rel_tol=0.0)
    assert tiny["objects"] == 1 and tiny["mask_iou_min"] == 1.0  # object 1 (100 px) is below min_pixels
    hole = depth.copy()
    hole[0, :6] = 0  # nothing drawn in one render: those pixels disagree
    assert agreement(depth, ids, hole, ids, min_pixels=10, depth_tol=0.01, depth_rel_tol=0.0)["depth_agree"] == round(
        1 - 6 / 2400, 4
    )


# ------------------------------------------------------------------ real Blender renders (slow)


def _need_blender():
    from refspatial_gen.sources.sim.blender_render import missing_reason, settings

    why = missing_reason(settings({}))
    if why:
        pytest.skip(f"Blender renderer not set up: {why}")


def _unit(key: str, cfg: dict, seed: int = 0):
    from refspatial_gen.run.plan import unit_rng
    from refspatial_gen.sources.sim import generate

    return generate(key, unit_rng(seed, key), cfg)


@pytest.mark.slow
def test_blender_frames_carry_mujoco_geometry_and_agree_with_blenders_own_passes(monkeypatch):
    _need_blender()
    from refspatial_gen.sources.sim import blender_render as br

    passes = []
    real = br.render_blender
    monkeypatch.setattr(br, "render_blender", lambda scene, cams, s: passes.extend(real(scene, cams, s)) or passes)
    fb = _unit("sim:000003", SMALL)
    fm = _unit("sim:000003", {k: v for k, v in SMALL.items() if k != "renderer"})
    assert [f.frame_id for f in fb] == [f.frame_id for f in fm] and len(passes) >= len(fb)
    for b, m, (rgb, depth, ids) in zip(fb, fm, passes):
        assert b.rgb.shape == m.rgb.shape == (72, 96, 3) and np.array_equal(b.rgb, rgb)
        assert np.abs(b.rgb.astype(int) - m.rgb.astype(int)).mean() > 2  # a different picture ...
        assert np.array_equal(b.depth, m.depth)  # ... of the same labels (MuJoCo's geometry)
        assert [(o.id, o.mask.to_json()) for o in b.objects] == [(o.id, o.mask.to_json()) for o in m.objects]
        chk = b.meta["render_check"]
        assert b.meta["renderer"] == "blender" and chk["mask_iou_min"] >= 0.8 and chk["depth_agree"] >= 0.97
        for o in b.objects:  # Blender's own object-index pass shows each visible object where MuJoCo does
            if o.mask.area >= 20:
                a, bl = o.mask.decode(), ids == o.id
                assert (a & bl).sum() / (a | bl).sum() > 0.8, o.id
        ok = (depth > 0) & (b.depth > 0)
        assert np.median(np.abs(depth[ok] - b.depth[ok])) < 1e-3  # Z pass converted to z-depth, metres


@pytest.mark.slow
def test_blender_render_is_deterministic_and_independent_of_threads():
    _need_blender()
    runs = [_unit("sim:000005", {**SMALL, "blender": {"samples": 4, "threads": t}}) for t in (1, 1, 2)]
    for frames in runs[1:]:
        assert all(np.array_equal(a.rgb, b.rgb) for a, b in zip(runs[0], frames))


@pytest.mark.slow
def test_disagreeing_passes_drop_the_unit(monkeypatch):
    _need_blender()
    from refspatial_gen.sources.sim import blender_render as br

    real = br.render_blender

    def shifted(scene, cams, s):  # Blender's masks two pixels off: the photo would not match the labels
        return [(rgb, depth, np.roll(ids, 2, axis=1)) for rgb, depth, ids in real(scene, cams, s)]

    monkeypatch.setattr(br, "render_blender", shifted)
    with pytest.raises(DropUnit) as e:
        _unit("sim:000003", {**SMALL, "blender": {"samples": 1, "min_mask_iou": 0.9, "min_pixels": 20}})
    assert e.value.reason == "renderer_disagree" and "mask IoU" in str(e.value)


@pytest.mark.slow
def test_a_missing_gpu_is_a_clear_drop_reason():
    _need_blender()
    from refspatial_gen.sources.sim.blender_render import BlenderWorker, blender_python, settings

    w = BlenderWorker(blender_python(settings({})))
    try:
        if w.request({"op": "probe"}, 120).get("devices"):
            pytest.skip("this machine has a GPU")
    finally:
        w.close()
    with pytest.raises(DropUnit) as e:
        _unit("sim:000003", {**SMALL, "blender": {"samples": 1, "device": "optix"}})
    assert e.value.reason == "render_failed" and "no OPTIX GPU" in str(e.value)


@pytest.mark.slow
def test_blender_camera_matches_opencv_intrinsics_off_centre_and_non_square():
    """Depth through every pixel centre of a floor and a wall (two planes: one plane alone cannot pin four
    intrinsics), ray-cast with our Camera model, equals Blender's Z pass: focal lengths (fx != fy both ways),
    principal point (lens shift) and pose are exact; the object-index pass shows the cube where it projects."""
    _need_blender()
    import trimesh

    from refspatial_gen.core.camera import Camera, look_at
    from refspatial_gen.sources.sim.blender_render import render_blender, settings
    from refspatial_gen.sources.sim.looks import Look
    from refspatial_gen.sources.sim.scene import MeshItem, RenderScene

    quad = np.array([[0, 1, 2], [0, 2, 3]])
    floor = np.array([[-9, -9, 0], [9, -9, 0], [9, 9, 0], [-9, 9, 0]], float)
    wall = np.array([[-9, 1.0, 0], [9, 1.0, 0], [9, 1.0, 9], [-9, 1.0, 9]], float)
    cube = trimesh.creation.box(extents=[0.2, 0.2, 0.2])
    T = look_at([0.7, -1.6, 1.3], [0.1, 0.2, 0.3])
    cams = [
        Camera(96, 72, 100.0, 100.0, 48.0, 36.0, T),
        Camera(96, 72, 100.0, 88.0, 41.0, 30.5, T),
        Camera(96, 72, 70.0, 84.0, 55.0, 40.0, look_at([-1.2, -0.8, 1.6], [0.0, 0.0, 0.1])),
    ]
    grey = Look((0.6, 0.6, 0.6, 1.0))
    at = np.eye(4)
    at[:3, 3] = [0.0, 0.0, 0.1]
    rs = RenderScene(
        [
            MeshItem("floor", 0, floor, quad, None, np.eye(4), grey),
            MeshItem("wall", 0, wall, quad, None, np.eye(4), grey),
            MeshItem("cube", 1, np.asarray(cube.vertices), np.asarray(cube.faces), None, at, grey),
        ],
        [
            {
                "kind": "directional",
                "pos": [0, 0, 3],
                "direction": [0, 0, -1],
                "color": [1, 1, 1],
                "intensity": 1.0,
                "base": 0.5,
                "diffuse": [0.5] * 3,
                "shadow": True,
                "cutoff_deg": 70,
            }
        ],
        cams,
        0.3,
    )

    class Described:
        def describe(self, cams):
            return rs

    outs = render_blender(Described(), cams, {**settings({}), "samples": 1})
    v, u = np.mgrid[0:72, 0:96] + 0.5
    for cam, (_rgb, depth, ids) in zip(cams, outs):
        d = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], -1) @ cam.world_from_cam[:3, :3].T
        p = cam.world_from_cam[:3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.stack([-p[2] / d[..., 2], (1.0 - p[1]) / d[..., 1]])  # z-depth to the floor and to the wall
        expect = np.where(t > 0, t, np.inf).min(axis=0)
        bg = ids == 0
        assert bg.sum() > 3000 and (ids == 1).sum() > 30 and np.isfinite(expect[bg]).all()
        assert np.allclose(depth[bg], expect[bg], rtol=2e-4, atol=2e-4), np.abs(depth[bg] - expect[bg]).max()
        uv, _ = cam.project(np.array([[0.0, 0.0, 0.2]]))  # the cube's top centre is drawn where the model says
        assert ids[int(uv[0, 1]), int(uv[0, 0])] == 1


@pytest.mark.slow
def test_a_scene_over_the_timeout_is_dropped_and_the_next_one_renders():
    _need_blender()
    with pytest.raises(DropUnit) as e:
        _unit("sim:000003", {**SMALL, "width": 320, "height": 240, "blender": {"samples": 256, "timeout_s": 1}})
    assert e.value.reason == "render_timeout"
    frames = _unit("sim:000003", SMALL)  # a fresh worker takes over
    assert frames and frames[0].meta["renderer"] == "blender"
