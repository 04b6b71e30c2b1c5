"""The cached perception pipeline with test-double models: a second pass never calls a model, batches are
fixed blocks, a computed result and a cached one are the same bytes, depth and intrinsics agree."""

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.perception.cache import Cache, array_hash, key_of
from refspatial_gen.perception.config import normalise
from refspatial_gen.perception.pipeline import Item, NeedsCompute, Perceiver
from tests.helpers.perception_fakes import FakeDepth, FakeDetector, FakeSegmenter, install, model_folder


def _items(rng, n=5, shape=(120, 160)):
    import cv2

    out = []
    for i in range(n):
        img = cv2.GaussianBlur(rng.integers(0, 256, (*shape, 3)).astype(np.uint8), (3, 3), 0)
        out.append(Item(f"img{i}", array_hash(img), img))
    return out


def _setup(tmp_path, monkeypatch, items, batch=2, depth=True):
    model_folder(tmp_path / "models", "det", "owlv2")
    model_folder(tmp_path / "models", "seg", "sam2")
    model_folder(tmp_path / "models", "dp", "depth_pro")
    det = FakeDetector({it.content: [((10, 10, 60, 60), "cup", 0.9), ((80, 20, 150, 100), "bowl", 0.8)]
                        for it in items[1:]})
    seg, dep = FakeSegmenter(), FakeDepth(focal=200.0, per_focal=True)
    install(monkeypatch, {"det": det, "seg": seg, "dp": dep})
    cfg = normalise({"models": str(tmp_path / "models"), "cache_dir": str(tmp_path / "cache"), "batch_size": batch,
                     "filters": {"min_side": 10, "blur_threshold": 0.0},
                     "detector": {"model": "det", "vocabulary": ["cup", "bowl"]}, "segmenter": {"model": "seg"},
                     **({"depth": {"model": "dp"}} if depth else {})})
    return Perceiver(cfg), det, seg, dep


def test_second_pass_reads_the_cache_and_calls_no_model(tmp_path, monkeypatch, rng):
    items = _items(rng)
    P, det, seg, dep = _setup(tmp_path, monkeypatch, items)
    first = P.run(items)
    assert isinstance(first[0], DropUnit) and first[0].reason == "no_detections"
    assert [len(r.detections) for r in first[1:]] == [2, 2, 2, 2]
    assert det.calls == [2, 2, 1] and dep.calls == [2, 2]  # batches of 2 in item order; image 0 has no boxes
    P2, det2, seg2, dep2 = _setup(tmp_path, monkeypatch, items)
    second = P2.run(items, may_compute=False)
    assert det2.calls == seg2.calls == dep2.calls == []
    for a, b in zip(first[1:], second[1:]):
        assert [(d.box, d.score, d.label) for d in a.detections] == [(d.box, d.score, d.label) for d in b.detections]
        assert all(np.array_equal(x, y) for x, y in zip(a.masks, b.masks))
        assert np.array_equal(a.depth.depth, b.depth.depth) and a.depth.focal == b.depth.focal == 200.0
    assert P2.cache.hits["detector"] == 5 and "detector" not in P2.cache.misses


def test_cache_only_pass_says_what_is_missing(tmp_path, monkeypatch, rng):
    items = _items(rng, 2)
    P, *_ = _setup(tmp_path, monkeypatch, items)
    with pytest.raises(NeedsCompute):
        P.run(items, may_compute=False)


def test_changing_a_threshold_reuses_the_model_outputs(tmp_path, monkeypatch, rng):
    items = _items(rng, 3)
    P, det, seg, _ = _setup(tmp_path, monkeypatch, items)
    P.run(items)
    n_det, n_seg = len(det.calls), len(seg.calls)
    P.cfg["detector"]["threshold"] = 0.85  # above the floor the cache was filled with: boxes reselected
    res = P.run(items)
    assert [[d.label for d in r.detections] for r in res[1:]] == [["cup"], ["cup"]]
    assert res[1].drops == {"below_threshold": 1}
    assert len(det.calls) == n_det and len(seg.calls) > n_seg  # new boxes need new masks, not new detections


def test_runtime_and_model_change_the_key(tmp_path):
    a = key_of("v", "detector", "img", "model1", ["cpu", 1, 4], [])
    assert a != key_of("v", "detector", "img", "model2", ["cpu", 1, 4], [])
    assert a != key_of("v", "detector", "img", "model1", ["cuda", 1, 4], [])
    assert a == key_of("v", "detector", "img", "model1", ["cpu", 1, 4], [])


def test_cache_roundtrip_and_off(tmp_path):
    c = Cache(tmp_path)
    c.put("s", "ab12", {"x": np.arange(3, dtype=np.float32)}, {"k": [1, "a"]})
    arr, meta = c.get("s", "ab12")
    assert arr["x"].dtype == np.float32 and arr["x"].tolist() == [0, 1, 2] and meta == {"k": [1, "a"]}
    assert not list(tmp_path.rglob("*.tmp"))
    (tmp_path / "s" / "ab" / "ab12.npz").write_bytes(b"truncated")
    assert c.get("s", "ab12") is None  # a broken entry is a miss, never an error
    off = Cache(None)
    off.put("s", "k", {"x": np.zeros(1)}, {})
    assert off.get("s", "k") is None


def test_depth_pro_style_depth_uses_the_chosen_focal(tmp_path, monkeypatch, rng):
    from refspatial_gen.perception import depth as dp

    items = _items(rng, 2)
    P, *_ = _setup(tmp_path, monkeypatch, items)
    res = P.run(items)[1]
    H, W = items[1].rgb.shape[:2]
    by_model = dp.resolve(["provided", "exif", "model", "prior"], None, W, H, 60.0, res.depth, "depth-pro")
    assert by_model.origin == "model:depth-pro" and by_model.fx == 200.0
    prior = dp.resolve(["prior"], None, W, H, 60.0, res.depth, "depth-pro")
    assert prior.origin == "fov_prior"
    d_model = dp.metric_depth(res.depth, by_model, 80.0)
    d_prior = dp.metric_depth(res.depth, prior, 80.0)
    ok = (d_model > 0) & (d_prior > 0)
    assert np.allclose(d_prior[ok] / d_model[ok], prior.fx / by_model.fx, rtol=1e-5)  # depth scales with f


def test_exif_focal_length_wins_over_the_model(tmp_path, rng):
    from PIL import Image

    from refspatial_gen.perception import depth as dp

    img = Image.fromarray(rng.integers(0, 256, (120, 160, 3)).astype(np.uint8))
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0xA405] = 28  # 35 mm-equivalent focal length
    img.save(tmp_path / "p.jpg", exif=exif)
    pred = dp.DepthPrediction(np.ones((120, 160), np.float32), True, 123.0)
    intr = dp.resolve(["provided", "exif", "model", "prior"], tmp_path / "p.jpg", 160, 120, 60.0, pred, "depth-pro")
    assert intr.origin == "exif_35mm" and abs(intr.fx - 28 * np.hypot(160, 120) / np.hypot(36, 24)) < 1e-6
