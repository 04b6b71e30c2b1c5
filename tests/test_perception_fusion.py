"""Multi-view fusion: one 3D object per instance across key frames, boxes where the objects are.

Synthetic: a ray-cast box world seen from three posed cameras (exact masks and depth). Real: the shared
ScanNet scene (three posed frames, depth splatted from its point cloud) with its annotated boxes
standing in for a detector (a test double that returns each frame's visible annotated objects)."""

import numpy as np
import pytest

from refspatial_gen.core.camera import Camera, look_at
from refspatial_gen.perception import fusion
from refspatial_gen.sources.toy import TABLE, toy_frame


@pytest.fixture(scope="module")
def views():
    """Six boxes on a table seen from three cameras (computed once: ray casting is the slow part)."""
    rng = np.random.default_rng(1234)
    first = toy_frame(rng, 6, 32, 24, frame_id="v0")
    boxes = [(o.category, o.attributes["color"], o.box) for o in first.objects]
    frames = []
    for k, yaw in enumerate((-0.6, 0.0, 0.6)):
        target = np.array([0.0, 0.0, TABLE.top_z])
        pitch = np.deg2rad(45)
        eye = target + 1.1 * np.array([np.sin(yaw) * np.cos(pitch), -np.cos(yaw) * np.cos(pitch), np.sin(pitch)])
        f = 320 / (2 * np.tan(np.deg2rad(30)))
        cam = Camera(320, 240, f, f, 160, 120, look_at(eye, target))
        frames.append(toy_frame(rng, boxes=boxes, camera=cam, frame_id=f"v{k}"))
    return boxes, frames


def _observations(frames, voxel, tag=lambda o: o.id):
    obs = []
    for f, fr in enumerate(frames):
        for o in fr.objects:
            codes, pts = fusion.lift(o.mask.decode(), fr.depth, fr.camera, voxel)
            if len(codes):
                obs.append(fusion.Observation(f, o.category, 1.0, codes, None, (float(tag(o)),), pts))
    return obs


def test_three_views_give_one_object_per_box(views):
    boxes, frames = views
    obs = _observations(frames, 0.01)
    objs, drops = fusion.finish(fusion.associate(obs, 0.01, 0.25), 0.01, 1, 10, True)
    seen = {o.id for fr in frames for o in fr.objects}
    assert len(objs) == len(seen) and drops == {}
    for obj, box in objs:
        ids = {o.bbox[0] for o in obj.observations}
        assert len(ids) == 1  # never two instances in one object
        truth = boxes[int(ids.pop()) - 1][2]
        assert len(set(obj.frames)) >= 2  # every box is seen from at least two of the three cameras
        assert np.linalg.norm(box.center[:2] - truth.center[:2]) < 0.02
        assert abs(box.top_z - truth.top_z) < 0.015
        area, true_area = box.size[0] * box.size[1], truth.size[0] * truth.size[1]
        assert 0.5 < area / true_area < 1.3  # the footprint; heights are what the cameras saw of the sides


def test_results_do_not_depend_on_observation_order(views):
    _, frames = views
    obs = _observations(frames, 0.01)
    a, _ = fusion.finish(fusion.associate(obs, 0.01, 0.25), 0.01, 1, 10, True)
    b, _ = fusion.finish(fusion.associate(obs[::-1], 0.01, 0.25), 0.01, 1, 10, True)
    assert [(o.label, tuple(np.round(bx.center, 6))) for o, bx in a] == [(o.label, tuple(np.round(bx.center, 6))) for o, bx in b]


def test_min_views_and_min_points_drop_by_reason(views):
    _, frames = views
    objs, drops = fusion.finish(fusion.associate(_observations(frames[:1], 0.01), 0.01, 0.25), 0.01, 2, 10, True)
    assert objs == [] and drops["fusion_too_few_views"] >= 1


def test_largest_component_drops_floaters():
    a = np.array([[x, 0, 0] for x in range(10)] + [[50, 50, 50], [51, 50, 50]], np.int64)
    assert len(fusion.largest_component(a)) == 10
    assert fusion.near(fusion.pack(np.array([[0, 0, 0], [5, 5, 5]])), fusion.pack(np.array([[1, 1, 1]]))).tolist() == [True, False]


def test_scannet_views_fuse_into_the_annotated_objects(shared_data):
    pytest.importorskip("open3d")
    from refspatial_gen.sources.scan.frames import view_to_frame
    from refspatial_gen.sources.scan.readers import get_reader

    root = shared_data / "scannet_scene0000_00"
    r = get_reader("scannet")
    cfg = {"min_visible_objects": 0, "max_width": 640, "unlabelled_stand_ins": False}  # annotated objects only
    frames = [view_to_frame(r.read(root, v, cfg), cfg) for v in r.views(root, cfg)]
    truth = {o.id: o for fr in frames for o in fr.objects}
    objs, _ = fusion.finish(fusion.associate(_observations(frames, 0.03), 0.03, 0.25), 0.03, 1, 10, True)
    pure = 0
    for obj, box in objs:
        ids = {o.bbox[0] for o in obj.observations}
        assert len(ids) == 1, f"{obj.label} fused two annotated instances {ids}"
        gt = truth[int(next(iter(ids)))]
        assert gt.category == obj.label
        # the fused points lie on the annotated object: its box (5 cm padding) holds them
        pts = (fusion.unpack(obj.voxels) + 0.5) * 0.03
        inside = gt.box.contains(pts, pad=0.05).mean()
        pure += inside >= 0.8
    assert pure >= len(objs) - 1
    # instances seen in two frames with overlapping parts are one object, not two
    by_id: dict[int, set] = {}
    for obj, _ in objs:
        by_id.setdefault(int(obj.observations[0].bbox[0]), set()).update(obj.frames)
    for oid in (7, 16, 20):  # desk, table, cabinet: visible in frames 00000 and 00011
        assert sum(int(o.observations[0].bbox[0]) == oid for o, _ in objs) == 1 and by_id[oid] == {0, 1}
    print(f"scannet: {len(objs)} fused objects from {len(truth)} annotated, {pure} with >= 80% of points inside")


def test_boxes_are_measured_on_points_not_on_the_voxel_grid(views):
    """Extents on the voxel grid make gaps between objects come in exact voxel steps, which tie with the
    scene graph's margins (a verify failure: above_world value 0.1000 = margin 0.1000). Fails on voxel centres."""
    _, frames = views
    objs, _ = fusion.finish(fusion.associate(_observations(frames, 0.01), 0.01, 0.25), 0.01, 1, 10, True)
    steps = np.array([box.size[2] / 0.01 for _, box in objs] + [box.center[2] / 0.005 for _, box in objs])
    assert not np.allclose(steps, np.round(steps), atol=1e-6)
