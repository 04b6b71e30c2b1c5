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
    assert estimator_names() == ["depth-anything", "geometric", "onnx", "provided"]
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
    cup = _rect(55, 72, 70, 85)  # its bottom sits inside the table's mask: it rests on the table
    kite = _rect(5, 20, 10, 30)  # entirely above the horizon, nothing under it
    res = est.estimate(None, _prior(masks=[(1, table), (2, cup), (3, kite)]))
    notes = res.meta["objects"]
    assert notes["1"]["contact"] == "ground" and notes["2"]["contact"] == "support:1"
    assert notes["3"]["reason"] == "no_ground_contact"
    assert abs(res.depth_m[60, 75] - res.depth_m[100, 75]) < 1e-4  # cup at the table's billboard depth
    # pitched down 10 degrees: the horizon moves up by f * tan(10deg), the same contact row is nearer
    pitched = get_estimator("geometric", {"camera_height": 1.5, "pitch_deg": 10.0}).estimate(None, _prior(masks=[(1, table)]))
    assert abs(pitched.meta["horizon_row"] - (60.0 - 100 * np.tan(np.deg2rad(10)))) < 1e-9
    assert pitched.meta["objects"]["1"]["contact_depth"] < res.meta["objects"]["1"]["contact_depth"]


def test_geometric_size_prior_conflict_and_fallback():
    toaster = _rect(62, 70, 70, 80)  # bottom just under the horizon: the far floor would make it huge
    p = _prior(masks=[(1, toaster)], categories={1: "toaster"})
    res = get_estimator("geometric", {"size_fallback": False}).estimate(None, p)
    assert res.meta["objects"]["1"]["reason"] == "size_prior_conflict"
    res = get_estimator("geometric", {"size_fallback": True}).estimate(None, p)
    assert res.meta["objects"]["1"]["contact"] == "size_prior"
    assert np.allclose(res.depth_m[toaster], 0.2 * 100.0 / 8, rtol=1e-5)  # typical 0.2 m over 8 rows


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
