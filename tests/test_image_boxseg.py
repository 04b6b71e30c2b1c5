"""Box-only annotations: depth layering of overlapping boxes (boxseg) and amodal completion (amodal) on a
small rendered scene: a wall, a floor, a bed front close to the camera and a night stand behind it."""

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.sources.image.amodal import complete_to_support, fit_to_box2d
from refspatial_gen.sources.image.boxseg import assign_boxes
from refspatial_gen.sources.image.gravity import world_from_cam

W, H, F, CAM_H = 160, 120, 100.0, 1.0


def _scene():
    """Depth + layer ids (0 wall, 1 floor, 2 bed, 3 night stand); camera 1 m up looking along world +y."""
    cam = Camera(W, H, F, F, W / 2, H / 2, world_from_cam(np.array([0.0, -1.0, 0.0]), CAM_H))
    vs, us = np.mgrid[0:H, 0:W] + 0.5
    depth = np.full((H, W), 6.0)  # the wall, fronto-parallel at 6 m
    layer = np.zeros((H, W), int)
    below = vs > H / 2
    floor = np.where(below, F * CAM_H / np.maximum(vs - H / 2, 1e-6), np.inf)
    m = floor < depth
    depth[m], layer[m] = floor[m], 1
    for lid, D, (x0, x1), (z0, z1) in ((3, 4.5, (0.6, 1.6), (0.0, 0.7)), (2, 3.0, (-1.2, 0.9), (0.0, 0.6))):
        u0, u1 = W / 2 + F * x0 / D, W / 2 + F * x1 / D
        v0, v1 = H / 2 + F * (CAM_H - z1) / D, H / 2 + F * (CAM_H - z0) / D
        m = (us >= u0) & (us < u1) & (vs >= v0) & (vs < v1) & (D < depth)
        depth[m], layer[m] = D, lid
    ok = depth > 0
    world = np.zeros((H, W, 3))
    world[ok] = cam.cam_to_world(cam.backproject(us[ok], vs[ok], depth[ok]))
    return cam, depth.astype(np.float32), layer, world


def _box_of(layer, lid):
    ys, xs = np.nonzero(layer == lid)
    return (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))


def test_overlapping_boxes_get_their_own_depth_layer():
    cam, depth, layer, world = _scene()
    boxes = [_box_of(layer, 2), _box_of(layer, 3)]
    x0, y0, x1, y1 = boxes[1]
    in_ns_box = layer[int(y0):int(y1), int(x0):int(x1)]
    assert np.mean(in_ns_box == 2) > 0.3  # the night stand's box is largely the bed in front of it
    n_wall = cam.cam_from_world[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # wall normal in world (camera axis)
    wall = (n_wall, -6.0 + float(n_wall @ cam.position))
    bm = assign_boxes(depth, world, boxes, support_z=[0.0], walls=[wall], cam=cam)
    bed, ns = bm.masks
    assert not np.any(bed & ns)
    assert np.all(layer[ns] == 3) and ns.sum() >= 0.8 * (layer == 3).sum()
    assert np.all(layer[bed] == 2) and bed.sum() >= 0.8 * (layer == 2).sum()


def test_support_completion_only_where_the_added_part_is_hidden():
    cam, depth, layer, _ = _scene()
    # the night stand's visible top, behind the bed: its lower part is hidden, so it reaches the floor
    top = Box3D(np.array([1.0, 4.7, 0.65]), np.array([0.8, 0.4, 0.1]), np.eye(3))
    done, notes = complete_to_support(top, depth, cam, [0.0])
    assert abs(done.bottom_z) < 1e-9 and abs(done.top_z - 0.7) < 1e-9 and "support_completed" in notes
    # a shelf on the wall to the left, with the wall visible under it: no completion down to the floor
    shelf = Box3D(np.array([-1.6, 5.8, 1.3]), np.array([0.5, 0.3, 0.2]), np.eye(3))
    same, notes = complete_to_support(shelf, depth, cam, [0.0])
    assert same is shelf and notes["support_completion"].startswith("would_be_visible")


def test_fit_to_box2d_raises_the_top_to_the_annotated_row():
    cam, *_ = _scene()
    box = Box3D(np.array([0.0, 4.0, 0.25]), np.array([0.6, 0.4, 0.5]), np.eye(3))
    uv, _ = cam.project(box.corners())
    bb = (float(uv[:, 0].min()), float(uv[:, 1].min()) - 20.0, float(uv[:, 0].max()), float(uv[:, 1].max()))
    fitted, notes = fit_to_box2d(box, bb, cam)
    assert fitted.top_z > box.top_z and fitted.bottom_z == box.bottom_z and "top_fitted_to_box2d" in notes
    assert abs(cam.project(fitted.corners())[0][:, 1].min() - bb[1]) < 1e-6
    same, notes = fit_to_box2d(box, (bb[0], uv[:, 1].min(), bb[2], bb[3]), cam)  # already reaches it
    assert same is box and not notes
