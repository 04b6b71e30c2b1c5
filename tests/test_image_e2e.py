"""End to end: `refspatial-gen shards` on COCO photos (geometric depth, and a tiny random Depth Anything),
then `verify` re-checks every QA pair on its independent code path."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


def _run(recipe: Path, inp: Path, out: Path, scenes: int) -> dict:
    from refspatial_gen.cli import main
    from refspatial_gen.qa.commands import verify_dir

    rc = main(["shards", "--recipe", str(recipe), "--input", str(inp), "--out", str(out), "--scenes", str(scenes),
               "--workers", "1", "--no-report", "--quiet"])
    assert rc == 0
    res = verify_dir(out)
    print(f"{recipe.name}: {res['qa_pairs']} QA pairs, {res['passed']} pass; failures: {res['failures'][:3]}")
    return res


def test_shards_from_coco_geometric_verify(shared_data, tmp_path):
    pytest.importorskip("open3d")
    res = _run(REPO / "recipes" / "image.yaml", shared_data / "coco_tiny_train2017", tmp_path / "out", 10)
    assert res["qa_pairs"] >= 30
    assert res["failed"] == 0


def test_shards_through_tiny_depth_anything_verify(shared_data, tmp_path):
    pytest.importorskip("open3d")
    pytest.importorskip("transformers")

    model_dir = _build_tiny_model(tmp_path / "model")
    text = (REPO / "recipes" / "image_depth_anything.yaml").read_text()
    text = text.replace("../models/depth-anything-v2-small", str(model_dir))
    text = text.replace("templates/", str(REPO / "recipes" / "templates") + "/")
    recipe = tmp_path / "image_da.yaml"
    recipe.write_text(text)
    res = _run(recipe, shared_data / "coco_tiny_train2017", tmp_path / "out", 8)
    assert res["qa_pairs"] >= 20
    # every pair the generator emits must pass the independent verifier
    assert res["failed"] == 0, res["failures"][:3]


def _build_tiny_model(d: Path) -> Path:
    import torch
    from transformers import DepthAnythingConfig, DepthAnythingForDepthEstimation, Dinov2Config

    backbone = Dinov2Config(hidden_size=32, num_hidden_layers=2, num_attention_heads=2, intermediate_size=64,
                            image_size=56, patch_size=14, out_features=["stage1", "stage2"], out_indices=[1, 2],
                            reshape_hidden_states=False)
    cfg = DepthAnythingConfig(backbone_config=backbone, reassemble_hidden_size=32, neck_hidden_sizes=[16, 32],
                              reassemble_factors=[2, 1], fusion_hidden_size=16, head_hidden_size=8)
    torch.manual_seed(0)
    model = DepthAnythingForDepthEstimation(cfg).eval()
    with torch.no_grad():
        model.head.conv3.weight.mul_(1e4)
        model.head.conv3.bias.fill_(1.0)
    try:
        from transformers import DPTImageProcessorPil as Proc
    except ImportError:
        from transformers import DPTImageProcessor as Proc
    proc = Proc(do_resize=True, size={"height": 56, "width": 56}, keep_aspect_ratio=False, ensure_multiple_of=14)
    model.save_pretrained(d)
    proc.save_pretrained(d)
    return d
