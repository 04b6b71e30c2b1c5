"""The `perception:` recipe section: defaults, checks before any work (missing model folder = file:line),
vocabularies shipped as data."""

import json
from pathlib import Path

import pytest

from refspatial_gen.core.errors import RecipeErrors
from refspatial_gen.perception.config import check_perception, model_entries, normalise, resolve_model
from refspatial_gen.perception.vocab import load_vocabulary, vocabulary_problem

REPO = Path(__file__).resolve().parents[1]


def _fake_model(root: Path, name: str, model_type: str, **extra) -> Path:
    d = root / name
    d.mkdir(parents=True)
    (d / "config.json").write_text(json.dumps({"model_type": model_type, **extra}))
    return d


def test_defaults_filled_and_entries_listed(tmp_path):
    _fake_model(tmp_path, "gd", "grounding-dino")
    _fake_model(tmp_path, "sam", "sam")
    cfg = normalise({"models": str(tmp_path), "detector": {"model": "gd"}, "segmenter": {"model": "sam"}})
    assert cfg["detector"]["threshold"] == 0.3 and cfg["detector"]["nms_iou"] == 0.5
    assert cfg["filters"]["blur_threshold"] == 20.0 and cfg["captions"]["colour"] is True
    assert cfg["fusion"]["voxel"] == 0.02 and cfg["intrinsics"] == ["provided", "exif", "model", "prior"]
    assert model_entries(cfg) == [("detector", "gd"), ("segmenter", "sam")]
    assert check_perception({"models": str(tmp_path), "detector": {"model": "gd"}, "segmenter": {"model": "sam"}}) is None


def test_problems_are_messages(tmp_path):
    _fake_model(tmp_path, "gd", "grounding-dino")
    _fake_model(tmp_path, "clip", "clip")
    _fake_model(tmp_path, "da_rel", "depth_anything", depth_estimation_type="relative")
    base = {"models": str(tmp_path), "detector": {"model": "gd"}}
    assert "does not exist" in check_perception({**base, "segmenter": {"model": "nope"}})
    assert "never downloaded" in check_perception({**base, "segmenter": {"model": "nope"}})
    assert "expected sam or sam2" in check_perception({**base, "segmenter": {"model": "clip"}})
    assert "relative" in check_perception({**base, "depth": {"model": "da_rel"}})
    assert "missing required key 'detector'" in check_perception({"models": str(tmp_path)})
    assert "unknown key 'treshold'" in check_perception({**base, "detector": {"model": "gd", "treshold": 0.2}})
    assert "must be <= 1" in check_perception({**base, "detector": {"model": "gd", "threshold": 2.0}})
    assert "vocabulary" in check_perception({**base, "detector": {"model": "gd", "vocabulary": "imagenet"}})
    assert "intrinsics" in check_perception({**base, "intrinsics": ["exif", "lidar"]})
    for bad in ("wide", True, 1.5, [0.3]):  # per-category scores were not checked before (a string ran)
        msg = check_perception({**base, "detector": {"model": "gd", "thresholds": {"person": bad}}})
        assert msg and "detector.thresholds.person" in msg, bad
    assert check_perception({**base, "detector": {"model": "gd", "thresholds": {"person": 0.5}}}) is None
    (tmp_path / "empty").mkdir()
    assert "no config.json" in check_perception({**base, "tagger": {"model": "empty"}})


def test_model_names_resolve_under_the_models_root(tmp_path, monkeypatch):
    monkeypatch.setenv("REFSPATIAL_MODELS", str(tmp_path / "env"))
    assert resolve_model("sam", None) == (tmp_path / "env" / "sam").resolve()
    assert resolve_model("sam", {"models": str(tmp_path / "r")}) == (tmp_path / "r" / "sam").resolve()
    assert resolve_model(str(tmp_path / "abs"), {"models": "x"}) == (tmp_path / "abs").resolve()


def test_missing_model_folder_is_a_recipe_error_with_file_and_line(tmp_path):
    from refspatial_gen.recipe import load_recipe

    text = (REPO / "recipes" / "photos.yaml").read_text()
    text = text.replace("templates/", str(REPO / "recipes" / "templates") + "/")
    text = text.replace("      perception:\n", f"      perception:\n        models: {tmp_path / 'no-models'}\n")
    recipe = tmp_path / "photos.yaml"
    recipe.write_text(text)
    with pytest.raises(RecipeErrors) as e:
        load_recipe(recipe)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.strip() == "perception:")
    msg = str(e.value)
    assert f"{recipe}:{line}:" in msg and "perception: detector.model" in msg and "does not exist" in msg


def test_shipped_vocabularies():
    assert len(load_vocabulary("coco")) == 80
    lvis = load_vocabulary("lvis")
    assert len(lvis) == 1203 and len(load_vocabulary("lvis-frequent")) == 405
    names = {c.name for c in lvis}
    assert "dining table" in names and "bus" in names  # "bus_(vehicle)" -> "bus"
    assert {"fish", "fish (food)", "salmon (fish)", "salmon (food)"} <= names  # a collision keeps its qualifier
    assert "computer monitor" in names and not any("_" in n for n in names)
    assert len(load_vocabulary("openimages")) == 601
    assert "coffee table" in {c.name for c in load_vocabulary("openimages")}


def test_user_vocabularies(tmp_path):
    assert [c.name for c in load_vocabulary(["Red_Mug", "chair", "chair"], exclude=["chair"])] == ["red mug"]
    f = tmp_path / "v.txt"
    f.write_text("# my list\ncup\n\nbowl\n")
    assert [c.name for c in load_vocabulary(str(f))] == ["cup", "bowl"]
    assert vocabulary_problem(str(tmp_path / "missing.txt")) and vocabulary_problem([]) and vocabulary_problem("x")
    assert vocabulary_problem("lvis") is None and vocabulary_problem(["a"]) is None


def test_vocabulary_sources_documented():
    text = (REPO / "refspatial_gen" / "perception" / "data" / "SOURCES.md").read_text()
    for f in ("lvis_v1_categories.tsv", "openimages_v7_boxable.tsv"):
        assert f in text
    assert text.count("CC BY 4.0") >= 2
