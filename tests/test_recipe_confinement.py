"""No recipe path can make the tool read or write outside its allowed roots: one test per route.

Routes: qa templates (absolute, climbing, symlinked), `input:`, source config paths (scan boxes_file, sim
catalog, image annotations / images_dir, depth model_dir / model_path), and the dataset name, which
becomes the output folder when no --out is given. A refused path is quoted as the recipe wrote it; the
file it names is never opened, so its contents never appear in an error."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.recipe import load_recipe
from refspatial_gen.recipe_paths import ALLOWED_ROOTS_ENV
from tests.helpers.runs import TEMPLATES

SECRET = "TOP-SECRET-LINE: the contents of a file outside the recipe's folder"


@pytest.fixture
def outside(tmp_path) -> Path:
    """A readable YAML-ish file outside the recipe's folder, with a recognisable line."""
    d = tmp_path / "elsewhere"
    d.mkdir()
    p = d / "secret.yaml"
    p.write_text(f"templates:\n  - {SECRET}\n")
    return p


def _recipe(folder: Path, *, template: str = "templates/locate.yaml", source: str = "  - kind: toy\n",
            name: str = "t") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "templates").exists():
        (folder / "templates").symlink_to(TEMPLATES)  # the shipped templates, beside the recipe
    p = folder / "r.yaml"
    p.write_text(f"name: {name}\nseed: 1\nscenes: 2\nsources:\n{source}qa:\n  families:\n"
                 f"    locate: {{weight: 1.0, templates: [{template}]}}\n")
    return p


def _errors(path: Path, **kw) -> list[str]:
    with pytest.raises((RecipeError, RecipeErrors)) as ei:
        load_recipe(path, **kw)
    e = ei.value
    return [str(x) for x in (e.errors if isinstance(e, RecipeErrors) else [e])]


def _lint(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "recipes", "lint", str(path)],
                          capture_output=True, text=True)


def test_shipped_and_local_templates_are_allowed(tmp_path):
    assert load_recipe(_recipe(tmp_path / "a")).qa.templates
    assert load_recipe(_recipe(tmp_path / "b", template=str(TEMPLATES / "locate.yaml"))).qa.templates


@pytest.mark.parametrize("kind", ["absolute", "climbing", "symlink"])
def test_template_outside_is_refused_and_never_read(tmp_path, outside, kind):
    folder = tmp_path / "proj"
    if kind == "absolute":
        ref = str(outside)
    elif kind == "climbing":
        ref = "../elsewhere/secret.yaml"
    else:
        folder.mkdir()
        (folder / "link.yaml").symlink_to(outside)
        ref = "link.yaml"
    p = _recipe(folder, template=ref)
    errs = _errors(p)
    assert any(":8: qa.families.locate.templates.0: path" in e and "outside the allowed folders" in e for e in errs), errs
    r = _lint(p)
    assert r.returncode == 1 and "outside the allowed folders" in r.stdout
    assert SECRET not in r.stdout + r.stderr and "Traceback" not in r.stderr


def test_etc_shadow_is_never_printed(tmp_path):
    r = _lint(_recipe(tmp_path / "p", template="/etc/shadow"))
    assert "/etc/shadow' is outside" in r.stdout
    assert "root:" not in r.stdout + r.stderr


def test_explicit_allow_root_lets_a_folder_in(tmp_path, outside, monkeypatch):
    p = _recipe(tmp_path / "proj", template=str(outside))
    errs = _errors(p, allow_roots=(str(outside.parent),))  # now read: its content is a template error, not a leak
    assert not any("outside the allowed folders" in e for e in errs)
    monkeypatch.setenv(ALLOWED_ROOTS_ENV, str(outside.parent))
    assert not any("outside the allowed folders" in e for e in _errors(p))


def test_input_outside_the_recipe_folder_is_refused(tmp_path):
    p = _recipe(tmp_path / "proj", source="  - kind: scan\n    input: ../data\n")
    (tmp_path / "data").mkdir()
    assert any(":6: sources.0.input: path '../data' is outside" in e for e in _errors(p))
    # inside the recipe's folder it is fine, and --input (the user's own choice) is always allowed
    p2 = _recipe(tmp_path / "proj2", source="  - kind: scan\n    input: data\n")
    (tmp_path / "proj2" / "data").mkdir()
    assert load_recipe(p2).sources[0].input == str((tmp_path / "proj2" / "data").resolve())
    assert load_recipe(p, input_path=str(tmp_path / "data")).sources[0].input == str(tmp_path / "data")


@pytest.mark.parametrize("source, key", [
    ("  - kind: scan\n    input: .\n    config: {boxes_file: /etc/passwd}\n", "sources.0.config.boxes_file"),
    ("  - kind: sim\n    config: {catalog: /etc/passwd}\n", "sources.0.config.catalog"),
    ("  - kind: image\n    input: .\n    config: {annotations: ../../etc/passwd}\n", "sources.0.config.annotations"),
    ("  - kind: image\n    input: .\n    config: {images_dir: /etc}\n", "sources.0.config.images_dir"),
    ("  - kind: image\n    input: .\n    config: {depth: {estimator: depth-anything, model_dir: /etc}}\n",
     "sources.0.config.depth.model_dir"),
    ("  - kind: image\n    input: .\n    config: {depth: {estimator: onnx, model_path: /etc/passwd}}\n",
     "sources.0.config.depth.model_path"),
])
def test_source_config_paths_are_confined(tmp_path, source, key):
    errs = _errors(_recipe(tmp_path / "proj", source=source))
    assert any(f"{key}: path" in e and "outside the allowed folders" in e for e in errs), errs


def test_input_folder_is_an_allowed_root_for_annotations(tmp_path):
    data = tmp_path / "data"
    (data / "ann").mkdir(parents=True)
    p = _recipe(tmp_path / "proj", source="  - kind: image\n    config: {annotations: ann/x.json}\n")
    load_recipe(p, input_path=str(data))  # resolved against the input folder: allowed


@pytest.mark.parametrize("name", ["../../../x", "/tmp/abs", "a/b", "..", ".hidden", "x" * 150])
def test_name_cannot_escape_the_output_root(tmp_path, name):
    p = _recipe(tmp_path / "proj", name=repr(name))
    cwd = tmp_path / "run" / "deep" / "cwd"
    cwd.mkdir(parents=True)
    r = subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "shards", "--recipe", str(p), "--workers", "1",
                        "--quiet", "--no-report"], capture_output=True, text=True, cwd=cwd,
                       env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert r.returncode == 2, r.stderr
    assert f"{p}:1: name: must be a plain folder name" in r.stderr
    assert "Traceback" not in r.stderr
    assert sorted(os.listdir(tmp_path)) == ["proj", "run"] and not list(cwd.iterdir())
