"""End to end: `refspatial-gen shards` on COCO photos (geometric depth, and a tiny random Depth Anything),
then `verify` re-checks every QA pair on its independent code path."""

from pathlib import Path

import pytest

from tests.helpers.depth_models import build_tiny_depth_anything

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


def _run(recipe: Path, inp: Path, out: Path, scenes: int) -> dict:
    from refspatial_gen.cli import main
    from refspatial_gen.tools.verify_dir import verify_dir

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

    model_dir = build_tiny_depth_anything(tmp_path / "model")
    text = (REPO / "recipes" / "image_depth_anything.yaml").read_text()
    text = text.replace("../models/depth-anything-v2-small", str(model_dir))
    text = text.replace("templates/", str(REPO / "recipes" / "templates") + "/")
    recipe = tmp_path / "image_da.yaml"
    recipe.write_text(text)
    # 16 photos: the truth checks (visibility floor, metric trust, photo size margins) withhold questions a
    # random-weight depth model cannot back, so 8 photos gave 19 pairs; enough pairs remain to test verify
    res = _run(recipe, shared_data / "coco_tiny_train2017", tmp_path / "out", 16)
    assert res["qa_pairs"] >= 20
    # every pair the generator emits must pass the independent verifier
    assert res["failed"] == 0, res["failures"][:3]
