"""Two runs in one process (a notebook, a test, a driver script) with the recipe file edited in between: the
second run reads the edited recipe (the executor's recipe cache is keyed by path; it once refused the run as
'changed during the run')."""

import json

from refspatial_gen.cli import main
from tests.helpers.runs import write_toy_recipe


def test_a_recipe_edited_between_two_runs_in_one_process_is_read_again(tmp_path, capsys):
    recipe = write_toy_recipe(tmp_path, scenes=2, per_shard=2)
    args = ["shards", "--recipe", str(recipe), "--workers", "1", "--quiet", "--no-report"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    recipe.write_text(recipe.read_text().replace("seed: 11", "seed: 12"))
    assert main([*args, "--out", str(tmp_path / "b")]) == 0, capsys.readouterr().err
    seeds = [json.loads((tmp_path / d / "index.json").read_text())["seed"] for d in "ab"]
    assert seeds == [11, 12]
