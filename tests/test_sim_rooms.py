"""Richer scenes: furnished rooms with several support surfaces at different heights, 3-9 objects on each
focus surface, lights in RefSpatial's range, and the renderer-neutral description of a settled scene."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from refspatial_gen.assets import load_catalog  # noqa: E402
from refspatial_gen.sources.sim import source  # noqa: E402


def _cfg(**kw):
    cat = load_catalog()
    cfg = source._cfg({"width": 160, "height": 120, **kw})
    cfg["_colors"] = cat.colors
    cfg["external_prob"] = 0.0
    return cat, cfg


def test_rooms_have_several_surfaces_at_different_heights_with_3_to_9_objects():
    from refspatial_gen.sources.sim.rooms import room_layout
    from refspatial_gen.sources.sim.source import _root_support

    cat, cfg = _cfg()
    counts = []
    for seed in range(8):
        desc = room_layout(cat, np.random.default_rng(seed), cfg)
        roots = [_root_support(desc, o) for o in desc.objects]
        held = {s.id: roots.count(s.id) for s in desc.surfaces if s.kind != "floor" and roots.count(s.id)}
        assert len(held) >= 2, (seed, held)
        heights = {round(s.z, 2) for s in desc.surfaces if s.id in held}
        assert len(heights) >= 2, (seed, heights)
        for sid in desc.focus:
            on = sum(1 for o in desc.objects if o.support == sid)  # directly on it (more may be stacked or inside)
            assert on <= 9, (seed, sid, on)
        assert max(held[s] for s in desc.focus if s in held) >= 3
        floor = next(s for s in desc.surfaces if s.kind == "floor")
        for i, a in enumerate(floor.fps):
            for b in floor.fps[i + 1:]:
                assert a.intersection(b).area < 1e-6  # furniture and floor objects never overlap
        counts.append(len(desc.objects))
    assert np.median(counts) >= 6


def test_lights_follow_refspatial_ranges():
    from refspatial_gen.sources.sim.lighting import sample_lights

    n, inten = set(), []
    for seed in range(40):
        ls = sample_lights(np.random.default_rng(seed), {"lights": [1, 3], "light_intensity": [0.6, 1.4], "shadows": True},
                           np.array([0, 0, 0.75]), np.array([2.5, 2.5]))
        n.add(len(ls))
        inten += [L.intensity for L in ls]
        assert ls[0].shadow and not any(L.shadow for L in ls[1:])
        assert all(abs(np.linalg.norm(L.direction) - 1) < 1e-9 and L.direction[2] < 0 for L in ls)
    assert n == {1, 2, 3} and 0.6 <= min(inten) < 0.7 and 1.3 < max(inten) <= 1.4


def test_room_scene_settles_renders_and_is_described_for_other_renderers(tmp_path):
    """The neutral description holds everything a second renderer needs: ray casting its meshes at their
    poses through its cameras gives MuJoCo's depth and instance ids."""
    import trimesh

    from refspatial_gen.sources.sim import generate
    from refspatial_gen.sources.sim.renderers import get_renderer, renderer_names
    from refspatial_gen.sources.sim.scene import SettledScene

    cat, cfg = _cfg()
    frames, desc, sim = generate("sim:000004", np.random.default_rng(4), {"width": 160, "height": 120, "views": 1,
                                                                          "layouts": {"room": 1.0}}, keep_scene=True)
    assert "mujoco" in renderer_names() and get_renderer("mujoco").name == "mujoco"
    with pytest.raises(KeyError):
        get_renderer("povray")
    f = frames[0]
    scene = SettledScene(desc, sim, cat.colors, cat.materials).describe([f.camera])
    assert {m.instance_id for m in scene.meshes} == set(range(len(desc.objects) + 1))
    assert 1 <= len(scene.lights) <= 3 and all(0.6 <= L["intensity"] <= 1.4 for L in scene.lights)
    out = scene.save(tmp_path / "scene")
    doc = json.loads((out / "scene.json").read_text())
    arrays = np.load(out / "meshes.npz")
    assert len(doc["meshes"]) == len(scene.meshes) and doc["cameras"][0]["fx"] == f.camera.fx
    tris, ids = [], []
    for item in doc["meshes"]:
        T = np.asarray(item["world_from_local"])
        v = arrays[f"v{item['arrays']}"] @ T[:3, :3].T + T[:3, 3]
        tris.append(v[arrays[f"f{item['arrays']}"]])
        ids += [item["instance_id"]] * len(arrays[f"f{item['arrays']}"])
    mesh = trimesh.Trimesh(*trimesh.triangles.to_kwargs(np.concatenate(tris)).values(), process=False)
    ids = np.asarray(ids)
    cam = f.camera
    vs, us = np.mgrid[5:120:10, 5:160:10]
    u, v = us.ravel(), vs.ravel()
    d = cam.world_from_cam[:3, :3] @ np.c_[(u + 0.5 - cam.cx) / cam.fx, (v + 0.5 - cam.cy) / cam.fy, np.ones(len(u))].T
    d = (d / np.linalg.norm(d, axis=0)).T
    loc, ray, tri = mesh.ray.intersects_location(np.repeat(cam.position[None], len(d), 0), d, multiple_hits=False)
    z = ((loc - cam.position) @ cam.world_from_cam[:3, 2])
    inst = np.zeros(len(u), int)
    inst[ray] = ids[tri]
    depth = np.zeros(len(u))
    depth[ray] = z
    mj_depth, mj_inst = f.depth[v, u], np.zeros(len(u), int)
    for o in f.objects:
        mj_inst[o.mask.decode()[v, u]] = o.id
    both = (depth > 0) & (mj_depth > 0)
    assert both.mean() > 0.9
    assert np.mean(np.abs(depth[both] - mj_depth[both]) < 0.01) > 0.97
    assert np.mean(inst == mj_inst) > 0.95
