"""Depth estimators without weights: provided encodings, geometric placement, scale recovery, registry."""

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.depth import CameraPrior, check_options, estimator_names, get_estimator
from refspatial_gen.depth.scale import recover_metric


def _prior(**kw) -> CameraPrior:
    base = dict(width=160, height=120, fx=100.0, fy=100.0, cx=80.0, cy=60.0)
    base.update(kw)
    return CameraPrior(**base)


def test_registry_and_option_checks():
    assert estimator_names() == ["depth-anything", "geometric", "onnx", "perception", "provided"]
    assert check_options("geometric", {"camera_height": 1.2}) is None
    assert "unknown option" in check_options("geometric", {"camera_hieght": 1.2})
    assert ">=" in check_options("geometric", {"camera_height": -1.0})
    assert "unknown depth estimator" in check_options("midas", {})
    with pytest.raises(ValueError):
        get_estimator("provided", {"encoding": "scale"})  # scale encoding needs its scale


@pytest.mark.parametrize("encoding,writer,expect", [
    ("mm", lambda d: np.round(d * 1000).astype(np.uint16), 1e-3),
    ("tum", lambda d: np.round(d * 5000).astype(np.uint16), 2e-4),
    ("float", lambda d: d.astype(np.float32), 1e-6),
])
def test_provided_encodings(tmp_path, encoding, writer, expect):
    import cv2

    d = np.linspace(0.5, 4.0, 160 * 120, dtype=np.float32).reshape(120, 160)
    d[0, :10] = 0.0  # missing
    path = tmp_path / ("d.tiff" if encoding == "float" else "d.png")
    assert cv2.imwrite(str(path), writer(d))
    res = get_estimator("provided", {"encoding": encoding}).estimate(None, _prior(depth_path=str(path)))
    assert res.is_metric and res.origin == f"provided:{encoding}"
    assert np.all(res.depth_m[0, :10] == 0)
    assert np.max(np.abs(res.depth_m - d)) <= expect


def test_provided_npy_and_bad_files(tmp_path):
    d = np.full((120, 160), 2.0, np.float32)
    np.save(tmp_path / "d.npy", d)
    res = get_estimator("provided").estimate(None, _prior(depth_path=str(tmp_path / "d.npy")))
    assert np.allclose(res.depth_m, 2.0)
    np.save(tmp_path / "small.npy", d[:50])
    with pytest.raises(DropUnit) as e:
        get_estimator("provided").estimate(None, _prior(depth_path=str(tmp_path / "small.npy")))
    assert e.value.reason == "depth_size_mismatch"
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(DropUnit) as e:
        get_estimator("provided").estimate(None, _prior(depth_path=str(tmp_path / "bad.png")))
    assert e.value.reason == "depth_unreadable"
    with pytest.raises(DropUnit) as e:
        get_estimator("provided").estimate(None, _prior(depth_path=str(tmp_path / "missing.png")))
    assert e.value.reason == "depth_missing"


def _rect(y0, y1, x0, x1, shape=(120, 160)):
    m = np.zeros(shape, bool)
    m[y0:y1, x0:x1] = True
    return m


def test_geometric_ground_contact_distance():
    """Camera 1.5 m high, level: the mask's lowest row is 89, its lower edge 90, 30 px under the
    principal point (60): it stands at z = h * f / 30 = 5 m, and all its pixels share that depth."""
    m = _rect(40, 90, 60, 80)
    res = get_estimator("geometric", {"camera_height": 1.5}).estimate(None, _prior(masks=[(1, m)]))
    z = 1.5 * 100.0 / 30.0
    assert np.allclose(res.depth_m[m], z, rtol=1e-5)
    assert np.all(res.depth_m[~m] == 0)
    note = res.meta["objects"]["1"]
    assert note["contact"] == "ground" and abs(note["contact_depth"] - z) < 1e-6


def test_geometric_pitch_support_and_failures():
    est = get_estimator("geometric", {"camera_height": 1.5, "size_fallback": False})
    table = _rect(70, 110, 20, 140)
    cup = _rect(64, 72, 70, 85)  # its bottom sits inside the table's mask: it rests on the table
    kite = _rect(5, 20, 10, 30)  # entirely above the horizon, nothing under it
    cats = {1: "dining table", 2: "cup", 3: "kite"}
    res = est.estimate(None, _prior(masks=[(1, table), (2, cup), (3, kite)], categories=cats))
    notes = res.meta["objects"]
    assert notes["1"]["contact"] == "ground" and notes["2"]["contact"] == "support:1"
    assert notes["3"]["reason"] == "no_ground_contact"
    assert abs(res.depth_m[66, 75] - res.depth_m[100, 75]) < 1e-4  # cup at the table's billboard depth
    # pitched down 10 degrees: the horizon moves up by f * tan(10deg), the same contact row is nearer
    pitched = get_estimator("geometric", {"camera_height": 1.5, "pitch_deg": 10.0}).estimate(None, _prior(masks=[(1, table)]))
    assert abs(pitched.meta["horizon_row"] - (60.0 - 100 * np.tan(np.deg2rad(10)))) < 1e-9
    assert pitched.meta["objects"]["1"]["contact_depth"] < res.meta["objects"]["1"]["contact_depth"]


def test_geometric_occluded_object_stands_behind_not_on():
    """A car whose lower half is hidden by a car in front (its mask ends on the front car's roof) was
    placed on that roof: "car on car". A car cannot bear a car: it now stands on the ground behind the
    front car, at the distance where its top row puts its top at a car's typical height (1.5 m)."""
    est = get_estimator("geometric", {"camera_height": 1.2})
    front = _rect(60, 110, 40, 120)  # contact row 110: 1.2 * 100 / 50 = 2.4 m away
    rear = _rect(55, 60, 60, 100)  # its bottom edge is the front car's roof line
    p = _prior(masks=[(1, front), (2, rear)], categories={1: "car", 2: "car"})
    notes = est.estimate(None, p).meta["objects"]
    assert notes["1"]["contact"] == "ground"
    assert notes["2"]["contact"] == "behind:1"
    d = notes["2"]["contact_depth"]
    assert d > notes["1"]["contact_depth"] + 1.0  # behind the car in front (and its 1.2 m depth)
    top = 1.2 - d * (55.0 - 60.0) / 100.0  # its top edge's height at that distance
    assert abs(top - 1.5) < 1e-6


def test_geometric_contact_must_be_seen_on_the_top_surface():
    """A table can bear a bottle, but a bottle whose bottom merely touches the table's top edge (no
    tabletop visible beside its foot) may stand behind the table: it does not rest on it."""
    est = get_estimator("geometric", {"camera_height": 1.5})
    table = _rect(70, 110, 20, 140)
    on_edge = _rect(62, 70, 70, 85)  # ends one row above the table's first row
    p = _prior(masks=[(1, table), (2, on_edge)], categories={1: "dining table", 2: "bottle"})
    notes = est.estimate(None, p).meta["objects"]
    assert notes["2"]["contact"].startswith("behind:1") or notes["2"].get("reason") == "contact_occluded"
    assert notes["2"]["contact"] != "support:1"


def test_geometric_size_prior_conflict_and_fallback():
    toilet = _rect(62, 76, 70, 80)  # bottom just under the horizon: the far floor would make it 1.24 m tall
    p = _prior(masks=[(1, toilet)], categories={1: "toilet"})  # at most 1.05 m (x 1.15)
    res = get_estimator("geometric", {"size_fallback": False}).estimate(None, p)
    assert res.meta["objects"]["1"]["reason"] == "size_prior_conflict"
    res = get_estimator("geometric", {"size_fallback": True}).estimate(None, p)
    assert res.meta["objects"]["1"]["contact"] == "size_prior"
    assert np.allclose(res.depth_m[toilet], 0.78 * 100.0 / 14, rtol=1e-5)  # typical 0.78 m over 14 rows


def test_camera_fit_recovers_height_and_pitch():
    """People and cars of known height standing at several distances fix the camera: a photo taken
    0.8 m high (from a car seat), pitched 5 degrees down, is recovered from its objects although the prior says 1.5 m,
    level (the prior would lift the people over 2.1 m tall). One odd object (a toddler) is outvoted."""
    from refspatial_gen.depth.camera_fit import Anchor, fit_camera, implied_height

    fy, cy, h, th = 500.0, 240.0, 0.8, np.deg2rad(5.0)

    def rows(height, dist):  # bottom and top rows of an upright object at this horizontal distance
        b = np.arctan2(h, dist) - th
        t = np.arctan2(h - height, dist) - th
        return cy + fy * np.tan(b), cy + fy * np.tan(t)

    objs = [("person", 1.75, 6.0), ("person", 1.62, 9.0), ("car", 1.45, 14.0), ("person", 1.8, 20.0),
            ("car", 1.9, 11.0), ("person", 0.85, 7.0)]
    anchors = [Anchor(k, c, *rows(H, d)) for k, (c, H, d) in enumerate(objs)]
    naive = implied_height(1.5, 0.0, fy, cy, anchors[0].v_bottom, anchors[0].v_top)
    assert naive is not None and naive > 2.1  # the level 1.5 m prior: a 1.75 m person lifted > 2.1 m
    fit = fit_camera(anchors, fy, cy, 1.5, 0.0)
    assert fit.source == "fit" and fit.status == "consistent" and len(fit.inliers) >= 5
    assert abs(fit.camera_height - h) < 0.15 and abs(np.rad2deg(fit.pitch) - 5.0) < 2.0
    for a in anchors[:5]:
        assert 1.1 <= implied_height(fit.camera_height, fit.pitch, fy, cy, a.v_bottom, a.v_top) <= 2.1
    # nothing of known size: the prior stays and the scale is unverified; one object alone fits any camera
    assert fit_camera([], fy, cy, 1.5, 0.0).status == "unverified"
    assert fit_camera(anchors[:1], fy, cy, 1.5, 0.0).status == "unverified"


def test_scale_recovery_from_contacts():
    """Affine disparity of a known depth map is mapped back to metres from the ground contacts."""
    est = get_estimator("geometric", {"camera_height": 1.5, "size_fallback": False})
    masks = [(1, _rect(30, 80, 10, 30)), (2, _rect(40, 100, 60, 80)), (3, _rect(20, 70, 110, 130))]
    p = _prior(masks=masks, camera_height=1.5, pitch=0.0)
    truth = est.estimate(None, p).depth_m
    assert all(truth[m].min() > 0 for _, m in masks)
    z = np.where(truth > 0, truth, 10.0)
    disparity = 3.0 / z + 0.2  # what a relative model predicts: unknown scale and shift
    depth, origin, meta = recover_metric(disparity, "disparity", p, "contacts", 1.5, 0.0, None, np.random.default_rng(0))
    assert origin == "scale:contacts" and meta["anchors"] == 3
    for _, m in masks:
        assert np.allclose(depth[m], truth[m], rtol=0.02)
    with pytest.raises(DropUnit) as e:
        recover_metric(disparity, "disparity", _prior(), "contacts", 1.5, 0.0, None, np.random.default_rng(0))
    assert e.value.reason == "depth_scale_unrecoverable"


def test_scale_recovery_from_camera_height():
    """A floor seen by a level camera 1.2 m high, predicted as depth up to scale 0.37."""
    p = _prior()
    vs, us = np.mgrid[0:120, 0:160].astype(float)
    below = vs > 62
    z = np.where(below, 1.2 * 100.0 / np.maximum(vs + 0.5 - 60.0, 1e-6), 0.0)
    rel = z * 0.37
    depth, origin, meta = recover_metric(rel, "depth", p, "camera_height", 1.2, 0.0, None, np.random.default_rng(0))
    assert origin == "scale:camera_height"
    assert np.allclose(depth[below], z[below], rtol=0.01)
