"""No traceback reaches a user: overrides are checked like the recipe, planning errors are `path: message`,
a run where every unit fails exits non-zero with the reasons, and anything unforeseen is one line plus the
log file that holds the traceback."""

import subprocess
import sys
from pathlib import Path

import pytest

from refspatial_gen import cli
from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources import register_source
from refspatial_gen.sources.toy import ToySource
from tests.helpers.runs import write_toy_recipe

REPO = Path(__file__).resolve().parents[1]


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "refspatial_gen.cli", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("flag, value, msg", [
    ("--scenes", "0", "--scenes: must be >= 1, got 0"), ("--scenes", "-5", "--scenes: must be >= 1, got -5"),
    ("--scenes", str(10**15), "--scenes: must be <= 1000000"), ("--seed", "-1", "--seed: must be >= 0, got -1"),
    ("--seed", str(2**70), "--seed: must be <= "), ("--workers", "0", "--workers: must be >= 1, got 0")])
def test_overrides_go_through_the_recipe_checks(tmp_path, flag, value, msg):
    recipe = write_toy_recipe(tmp_path)
    r = _cli("shards", "--recipe", str(recipe), "--out", str(tmp_path / "out"), flag, value, "--quiet")
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().startswith(msg), r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "out").exists()


@pytest.mark.parametrize("weights", ["[0, 0]", "[.nan, 1]"])
def test_lint_refuses_zero_or_nan_weights(tmp_path, weights):
    recipe = write_toy_recipe(tmp_path)
    w = weights.strip("[]").split(", ")
    recipe.write_text(recipe.read_text().replace("  - kind: toy\n", f"  - kind: toy\n    weight: {w[0]}\n"
                                                 f"  - kind: toy\n    weight: {w[1]}\n"))
    r = _cli("recipes", "lint", str(recipe))
    assert r.returncode == 1
    assert ("every source has weight 0" in r.stdout) or ("weight must be a finite number, got nan" in r.stdout), r.stdout


@pytest.mark.parametrize("make, msg", [
    (lambda p: p.mkdir(), "input folder is empty"), (lambda p: None, "input does not exist"),
    (lambda p: p.write_text("x"), "input must be a folder (the image source reads a folder of annotations and images)")])
def test_unusable_input_root_stops_before_work(tmp_path, make, msg):
    inp = tmp_path / "in"
    make(inp)
    r = _cli("shards", "--recipe", str(REPO / "recipes" / "image.yaml"), "--input", str(inp), "--out",
             str(tmp_path / "out"), "--quiet", "--workers", "1")
    assert r.returncode == 2 and r.stderr.strip() == f"{inp}: {msg}", r.stderr
    assert not (tmp_path / "out").exists()


class AlwaysDrops(ToySource):
    name = "always_drops"

    def load(self, unit_key, rng, config):
        raise DropUnit("sensor_offline", unit_key)


def test_a_run_where_every_unit_fails_exits_1_with_the_reasons(tmp_path, capsys):
    register_source("always_drops", "tests.test_cli_errors:AlwaysDrops")
    recipe = write_toy_recipe(tmp_path, scenes=3)
    recipe.write_text(recipe.read_text().replace("kind: toy", "kind: always_drops"))
    rc = cli.main(["shards", "--recipe", str(recipe), "--out", str(tmp_path / "out"), "--workers", "1", "--quiet",
                   "--no-report"])
    err = capsys.readouterr().err
    assert rc == 1 and "every unit was dropped; top reasons: sensor_offline (3)" in err


def test_an_unforeseen_error_is_one_line_and_a_log_file(tmp_path, monkeypatch, capsys):
    import refspatial_gen.run.executor as ex

    def boom(*a, **k):
        raise ZeroDivisionError("planted")

    monkeypatch.setattr(ex, "run_plan", boom)
    monkeypatch.delenv("REFSPATIAL_DEBUG", raising=False)
    rc = cli.main(["shards", "--recipe", str(write_toy_recipe(tmp_path)), "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1, err
    assert err[0].startswith("refspatial-gen: internal error: ZeroDivisionError: planted; details in ")
    log = err[0].rsplit("details in ", 1)[1]
    assert "Traceback" in open(log).read() and "boom" in open(log).read()


def test_ctrl_c_outside_a_run_is_one_line(tmp_path, monkeypatch, capsys):
    import refspatial_gen.recipe as rec

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(rec, "load_recipe", interrupted)
    rc = cli.main(["shards", "--recipe", "x.yaml", "--quiet"])
    assert rc == 130 and capsys.readouterr().err.strip() == "refspatial-gen: interrupted (Ctrl-C)"


def test_stats_of_a_folder_without_index_is_one_line(tmp_path):
    r = _cli("stats", str(tmp_path))
    assert r.returncode != 0 and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
