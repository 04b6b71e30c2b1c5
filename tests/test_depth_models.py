"""Model-based depth: a tiny randomly initialised Depth Anything (built from a config, saved to a
temporary folder, loaded back offline) and a tiny ONNX depth model, run through the whole image source.

Skipped when torch/transformers (or onnx/onnxruntime) are not installed; CI installs them."""


import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.depth import CameraPrior, get_estimator
from refspatial_gen.sources.image import ImageSource
from tests.helpers.depth_models import build_tiny_depth_anything


@pytest.fixture(scope="module")
def tiny_depth_anything(tmp_path_factory):
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    return build_tiny_depth_anything(tmp_path_factory.mktemp("tiny_depth_anything"))


def _masks_prior(h=120, w=160):
    m1 = np.zeros((h, w), bool)
    m1[40:100, 20:60] = True
    m2 = np.zeros((h, w), bool)
    m2[50:80, 90:140] = True
    m3 = np.zeros((h, w), bool)
    m3[30:70, 70:85] = True
    return CameraPrior(w, h, 120.0, 120.0, (w - 1) / 2, (h - 1) / 2, 1.5, 0.0, masks=[(1, m1), (2, m2), (3, m3)])


def test_depth_anything_estimator_offline(tiny_depth_anything):
    est = get_estimator("depth-anything", {"model_dir": str(tiny_depth_anything)})
    rgb = np.random.default_rng(0).integers(0, 255, (120, 160, 3), dtype=np.uint8)
    res = est.estimate(rgb, _masks_prior())
    assert res.depth_m.shape == (120, 160) and res.depth_m.dtype == np.float32
    assert res.is_metric and res.origin == "depth-anything:disparity+scale:contacts"
    assert np.all(np.isfinite(res.depth_m)) and np.median(res.depth_m) > 0
    # the scale was fitted to the geometric contacts: the anchors' depths are reproduced at their pixels
    assert res.meta["anchors"] == 3
    again = est.estimate(rgb, _masks_prior())
    assert np.array_equal(res.depth_m, again.depth_m)  # deterministic
    relative = get_estimator("depth-anything", {"model_dir": str(tiny_depth_anything), "scale_recovery": "none"})
    assert not relative.estimate(rgb, _masks_prior()).is_metric


def test_depth_anything_never_downloads(tmp_path):
    with pytest.raises(ValueError, match="never downloaded"):
        get_estimator("depth-anything", {"model_dir": str(tmp_path / "LiheYoung-depth-anything-small-hf")})


def test_depth_anything_through_the_image_source(tiny_depth_anything, shared_data):
    """The whole path: COCO photos -> tiny Depth Anything -> scale recovery -> gravity -> lifted frames."""
    pytest.importorskip("open3d")
    src = ImageSource()
    cfg = {"depth": {"estimator": "depth-anything", "model_dir": str(tiny_depth_anything)}, "gravity": "prior",
           "_input": str(shared_data / "coco_tiny_train2017")}
    keys = src.unit_keys(cfg, None, str(shared_data / "coco_tiny_train2017"))
    frames, reasons = [], []
    for k in keys[:8]:
        try:
            frames.append(src.load(k, np.random.default_rng(0), cfg)[0])
        except DropUnit as e:
            reasons.append(e.reason)
    assert frames, reasons
    for f in frames:
        f.validate()
        assert f.meta["depth"]["origin"] == "depth-anything:disparity+scale:contacts"
        for o in f.objects:
            assert o.mask.area > 0 and np.all(np.isfinite(o.box.center))
    cfg_rel = {"depth": {"estimator": "depth-anything", "model_dir": str(tiny_depth_anything), "scale_recovery": "none"},
               "_input": cfg["_input"]}
    with pytest.raises(DropUnit) as e:
        src.load(keys[0], np.random.default_rng(0), cfg_rel)
    assert e.value.reason in ("depth_not_metric", "too_few_objects")


@pytest.fixture(scope="module")
def tiny_onnx(tmp_path_factory):
    onnx = pytest.importorskip("onnx")
    pytest.importorskip("onnxruntime")
    from onnx import TensorProto, helper

    # disparity = 2 + mean over colour channels: positive, image-dependent, 1x32x32 for a 1x3x32x32 input
    inp = helper.make_tensor_value_info("pixel_values", TensorProto.FLOAT, [1, 3, 32, 32])
    out = helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, 32, 32])
    axes = helper.make_tensor("axes", TensorProto.INT64, [1], [1])
    two = helper.make_tensor("two", TensorProto.FLOAT, [], [2.0])
    g = helper.make_graph([helper.make_node("ReduceMean", ["pixel_values", "axes"], ["m"], keepdims=0),
                           helper.make_node("Add", ["m", "two"], ["disparity"])], "tiny", [inp], [out],
                          initializer=[axes, two])
    model = helper.make_model(g, opset_imports=[helper.make_opsetid("", 18)])
    model.ir_version = 9
    onnx.checker.check_model(model)
    p = tmp_path_factory.mktemp("onnx") / "tiny_depth.onnx"
    onnx.save(model, str(p))
    return p


def test_onnx_estimator(tiny_onnx):
    est = get_estimator("onnx", {"model_path": str(tiny_onnx), "output": "disparity", "mean": [0, 0, 0],
                                 "std": [1, 1, 1]})  # disparity in [2, 3]: every pixel has a depth
    rgb = np.random.default_rng(1).integers(0, 255, (120, 160, 3), dtype=np.uint8)
    res = est.estimate(rgb, _masks_prior())
    assert res.origin == "onnx:disparity+scale:contacts" and res.is_metric
    assert res.depth_m.shape == (120, 160) and np.all(res.depth_m > 0)
    # a metric model's output is taken as metres: 2 + mean of normalised pixels
    metric = get_estimator("onnx", {"model_path": str(tiny_onnx), "output": "metric", "mean": [0, 0, 0], "std": [1, 1, 1]})
    flat = np.full((120, 160, 3), 255, np.uint8)
    assert np.allclose(metric.estimate(flat, _masks_prior()).depth_m, 3.0, atol=1e-4)
