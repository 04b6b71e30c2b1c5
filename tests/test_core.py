import json

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from refspatial_gen.core import RLE, Box3D, Camera, Frame, SceneGraph
from refspatial_gen.core.camera import look_at
from refspatial_gen.core.geometry import box_distance, inside_fraction
from refspatial_gen.core.mask import answer_pixel, denormalise_point, normalise_point
from refspatial_gen.core.serialize import decode_depth, decode_image, dumps, encode_depth, encode_png


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 30), st.integers(1, 30), st.integers(0, 2**31 - 1))
def test_rle_round_trip(h, w, seed):
    m = np.random.default_rng(seed).random((h, w)) > 0.5
    r = RLE.encode(m)
    assert (r.decode() == m).all()
    assert r.area == m.sum()
    assert RLE.from_json(json.loads(json.dumps(r.to_json()))) == r


def test_answer_point_inside_largest_part_even_for_ring():
    m = np.zeros((60, 80), bool)
    m[10:50, 10:50] = True
    m[20:40, 20:40] = False  # ring: centroid falls in the hole
    m[0:3, 70:73] = True  # small second part
    x, y = answer_pixel(m)
    assert m[int(y), int(x)]
    assert 10 <= x < 50
    p = normalise_point(x, y, 80, 60)
    px, py = denormalise_point(*p, 80, 60)
    assert m[py, px]


def test_box_geometry():
    a = Box3D.from_yaw([0, 0, 0.5], [1, 1, 1])
    b = Box3D.from_yaw([2, 0, 0.5], [1, 1, 1])
    assert abs(box_distance(a, b) - 1.0) < 1e-9
    assert box_distance(a, a) == 0.0
    assert inside_fraction(Box3D.from_yaw([0, 0, 0.5], [0.2, 0.2, 0.2]), a) == 1.0
    assert inside_fraction(b, a) == 0.0
    assert abs(Box3D.from_yaw([0, 0, 0], [1, 2, 3], 0.7).yaw - 0.7) < 1e-12


def test_camera_projection_round_trip():
    cam = Camera(640, 480, 500, 500, 320, 240, look_at([0, -1, 1], [0, 0, 0]))
    pts = np.array([[0.1, 0.2, 0.0], [-0.3, 0.1, 0.2]])
    uv, z = cam.project(pts)
    back = cam.cam_to_world(cam.backproject(uv[:, 0], uv[:, 1], z))
    assert np.allclose(back, pts)
    assert np.allclose(cam.gravity_cam @ cam.world_to_cam(np.array([[0, 0, 0]]))[0] * 0, 0)
    # the camera looks down: gravity has a positive y (down) component in the camera frame
    assert cam.gravity_cam[1] > 0


def test_frame_and_graph_json_round_trip(toy_frame):
    f = toy_frame
    f.validate()
    meta = json.loads(dumps(f.meta_json()))
    depth = decode_depth(encode_depth(f.depth), f.camera.height, f.camera.width)
    rgb = decode_image(encode_png(f.rgb))
    g = Frame.from_meta_json(meta, rgb, depth)
    assert (g.depth == f.depth).all() and (g.rgb == f.rgb).all()
    assert dumps(g.meta_json()) == dumps(f.meta_json())
    sg = SceneGraph(f.frame_id, [], [], [], {"scale": "tabletop"})
    assert SceneGraph.from_json(json.loads(dumps(sg.to_json()))).meta == {"scale": "tabletop"}


def test_toy_frame_is_consistent(toy_frame):
    f = toy_frame
    for o in f.objects:
        m = o.mask.decode()
        ys, xs = np.nonzero(m)
        pts = f.camera.cam_to_world(f.camera.backproject(xs + 0.5, ys + 0.5, f.depth[ys, xs]))
        assert o.box.contains(pts, pad=1e-4).mean() > 0.99
