"""Every model family: a tiny random model built from its config, saved with save_pretrained, loaded back
from the folder (never downloaded) and run by its runner on a real photo; outputs have the right shapes
and repeat exactly for the same batch. A photo's numbers in a batch of two and alone agree to float
rounding only (measured here: last-bit differences on CPU), which is why the pipeline batches in fixed
blocks: the same batch, the same bytes."""

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    pytest.importorskip("transformers")
    pytest.importorskip("sentencepiece")
    from refspatial_gen.perception.random_models import build_all

    return build_all(tmp_path_factory.mktemp("models"))


@pytest.fixture(scope="module")
def photos():
    from tests.conftest import SHARED_DATA

    from refspatial_gen.sources.image.source import decode_rgb

    files = sorted((SHARED_DATA / "coco_tiny_train2017" / "images").glob("*.jpg"))
    if not files:
        pytest.skip("shared COCO photos not found")
    return [decode_rgb(f) for f in files[:3]]


def _batch(photos, fam):
    """Two photos to batch: of different sizes, or of one size for families whose input follows the size
    (the pipeline batches those only by size)."""
    from refspatial_gen.perception.pipeline import SIZE_BATCHED

    return [photos[0], np.ascontiguousarray(photos[0][::-1])] if fam in SIZE_BATCHED else photos[:2]


def _runner(path: Path):
    from refspatial_gen.perception.runtime import Runtime, load_model

    return load_model(str(path), Runtime("cpu", 1, 2))


def test_every_folder_passes_the_recipe_check(models):
    from refspatial_gen.perception.config import ROLE_FAMILIES, model_problem
    from refspatial_gen.perception.registry import family_of
    from refspatial_gen.perception.runtime import read_config

    for fam, path in models.items():
        assert family_of(read_config(path)) == fam
        role = next(r for r, fams in ROLE_FAMILIES.items() if fam in fams)
        assert model_problem(str(path), None, ROLE_FAMILIES[role]) is None
        assert (path / "RANDOM_WEIGHTS.txt").is_file()


@pytest.mark.parametrize("fam", ["grounding-dino", "owlv2"])
def test_detectors(models, photos, fam):
    from refspatial_gen.perception.vocab import load_vocabulary

    run = _runner(models[fam])
    names = [c.name for c in load_vocabulary("coco")]
    batch = _batch(photos, fam)
    a = run.detect(batch, names, names, 0.0, 20)
    assert len(a) == 2 and all(len(d) > 0 for d in a)
    for dets, img in zip(a, batch):
        H, W = img.shape[:2]
        for d in dets[:50]:
            assert d.label in names and 0.0 <= d.score <= 1.0 and len(d.box) == 4
            assert -W < d.box[0] < 2 * W and -H < d.box[1] < 2 * H
    again = run.detect(batch, names, names, 0.0, 20)
    assert [[(d.box, d.score, d.label) for d in x] for x in again] == [[(d.box, d.score, d.label) for d in x] for x in a]
    alone = run.detect(batch[1:], names, names, 0.0, 20)[0]
    close = [d for d in alone if any(e.label == d.label and np.allclose(e.box, d.box, atol=1e-2) for e in a[1])]
    assert len(close) >= 0.9 * len(alone)


@pytest.mark.parametrize("fam", ["sam", "sam2"])
def test_segmenters(models, photos, fam):
    run = _runner(models[fam])
    boxes = [[(10.0, 20.0, 200.0, 220.0), (50.0, 60.0, 120.0, 90.0)], [(0.0, 0.0, 30.0, 30.0)]]
    out = run.segment(photos[:2], boxes, True)
    assert [len(m) for m, _ in out] == [2, 1]
    for (masks, scores), img in zip(out, photos):
        assert all(m.shape == img.shape[:2] and m.dtype == bool for m in masks) and len(scores) == len(masks)
    again = run.segment(photos[1:2], boxes[1:], True)
    assert np.array_equal(again[0][0][0], out[1][0][0])


@pytest.mark.parametrize("fam", ["depth-anything", "depth-pro", "zoedepth"])
def test_metric_depth(models, photos, fam):
    run = _runner(models[fam])
    batch = _batch(photos, fam)
    preds = run.predict(batch)
    for p, img in zip(preds, batch):
        assert p.depth.shape == img.shape[:2] and p.depth.dtype == np.float32 and np.isfinite(p.depth).all()
        assert p.per_focal == (fam == "depth-pro")
        assert (p.focal is None) if fam != "depth-pro" else (p.focal is None or p.focal > 0)
    assert all(np.array_equal(x.depth, y.depth) for x, y in zip(run.predict(batch), preds))
    single = run.predict(batch[1:])[0]
    assert np.allclose(single.depth, preds[1].depth, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("fam", ["clip", "siglip"])
def test_image_text_scores(models, photos, fam):
    run = _runner(models[fam])
    p = run.scores(photos[:2], ["a photo of a room", "a screenshot", "a cup"])
    assert p.shape == (2, 3) and ((p >= 0) & (p <= 1)).all()
    if fam == "clip":
        assert np.allclose(p.sum(axis=1), 1.0, atol=1e-5)  # softmax over the prompts asked together


def test_vlm_describes_a_crop(models, photos):
    run = _runner(models["vlm"])
    out = run.describe([photos[0][:100, :100]], ["Describe the cup in a few words."], 5)
    assert len(out) == 1 and isinstance(out[0], str)
    assert out == run.describe([photos[0][:100, :100]], ["Describe the cup in a few words."], 5)  # greedy
