"""External YCB / object_sim meshes, imported with one command each, give verified questions."""

from pathlib import Path

import pytest

from refspatial_gen.tools.verify_dir import verify_dir
from refspatial_gen.recipe import load_recipe
from refspatial_gen.run.executor import RecipeRef, run_plan
from refspatial_gen.shards.reader import read_sample_meta

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
YCB = {"cracker box", "tomato soup can", "mustard bottle", "gelatin box", "power drill"}


def test_ycb_scenes_give_verified_questions(shared_data, tmp_path):
    from refspatial_gen.assets.importer import import_assets

    for name in ("ycb_sim", "object_sim"):  # what `make assets-shared` does, when it has not been run
        out = REPO / "out" / "assets" / f"{name}.yaml"
        if not out.exists():
            import_assets([shared_data / name], out)
    recipe_path = str(REPO / "recipes" / "sim_ycb.yaml")
    recipe = load_recipe(recipe_path, scenes=4)
    res = run_plan(recipe, RecipeRef(recipe_path, None, 4, None), tmp_path, workers=1, strict=True, progress=False)
    assert res["stats"]["qa_pairs"] > 0
    cats = set()
    for shard in sorted(tmp_path.glob("shard-*.mcap")):
        for s in read_sample_meta(shard):
            for f in s["frames"]:
                cats.update(o["category"] for o in f["objects"])
    assert cats & YCB, cats
    summary = verify_dir(tmp_path)
    assert summary["qa_pairs"] == res["stats"]["qa_pairs"] and summary["failed"] == 0, summary["failures"][:5]
