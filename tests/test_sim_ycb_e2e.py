"""External YCB / object_sim meshes in simulated scenes render, settle and give verified questions."""

import pytest

from refspatial_gen.tools.verify_dir import verify_dir
from refspatial_gen.recipe import load_recipe
from refspatial_gen.run.executor import RecipeRef, run_plan
from refspatial_gen.shards.reader import read_sample_meta

pytestmark = pytest.mark.slow

YCB = {"cracker box", "tomato soup can", "mustard bottle", "gelatin box", "power drill"}


def test_ycb_scenes_give_verified_questions(shared_data, tmp_path):
    recipe_path = "recipes/sim_ycb.yaml"
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
