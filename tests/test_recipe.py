"""Recipe errors stop the run before any work, as `file:line: message`."""

import subprocess
import sys
from pathlib import Path

import pytest

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.recipe import load_recipe

GOOD_HEAD = "name: t\nseed: 1\nscenes: 4\n"


def _errors(tmp_path: Path, text: str) -> list[str]:
    p = tmp_path / "r.yaml"
    p.write_text(text)
    with pytest.raises((RecipeError, RecipeErrors)) as ei:
        load_recipe(p)
    e = ei.value
    return [str(x) for x in (e.errors if isinstance(e, RecipeErrors) else [e])]


def test_unknown_key_reports_its_line(tmp_path):
    errs = _errors(tmp_path, GOOD_HEAD + "sources:\n  - kind: toy\n    wieght: 2\n")
    assert any(e.startswith(f"{tmp_path / 'r.yaml'}:6: unknown key 'wieght'") for e in errs), errs


def test_wrong_type_reports_its_line(tmp_path):
    errs = _errors(tmp_path, "name: t\nseed: one\nsources:\n  - kind: toy\n")
    assert any(":2: seed must be an integer" in e for e in errs), errs


def test_yaml_syntax_error_reports_its_line(tmp_path):
    errs = _errors(tmp_path, GOOD_HEAD + "sources: [\n  {kind: toy\n")
    assert len(errs) == 1 and ": YAML syntax:" in errs[0]
    assert int(errs[0].split(":")[1]) >= 5


def test_unknown_source_and_bad_range(tmp_path):
    errs = _errors(tmp_path, GOOD_HEAD + "sources:\n  - kind: nope\nshards:\n  samples_per_shard: 0\n")
    assert any(":5: unknown source kind 'nope'" in e for e in errs), errs
    assert any(":7: shards.samples_per_shard must be >= 1" in e for e in errs), errs


def test_missing_sources(tmp_path):
    errs = _errors(tmp_path, GOOD_HEAD)
    assert any("missing required key 'sources'" in e for e in errs)


def test_cli_stops_before_any_work(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text(GOOD_HEAD + "sources:\n  - kind: toy\n    config: 3\n")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "shards", "--recipe", str(p), "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode != 0
    assert f"{p}:6: sources.0.config must be a mapping" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert not out.exists()
