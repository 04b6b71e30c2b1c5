"""Catalog files: include: extends, paths resolve against the naming file, every path checked at load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from refspatial_gen.assets import build_geometry, load_catalog
from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.tools.lint import lint_file

REPO = Path(__file__).resolve().parents[1]


def _errors(fn):
    try:
        fn()
    except RecipeErrors as e:
        return e.errors
    except RecipeError as e:
        return [e]
    return []


def _mesh(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=[0.1, 0.06, 0.04]).export(path)


def test_include_extends_the_builtin_catalog_with_paths_relative_to_the_file(tmp_path, monkeypatch):
    _mesh(tmp_path / "lib" / "meshes" / "brick.stl")
    (tmp_path / "lib" / "cat.yaml").write_text(
        "include: builtin\ncolors:\n  teal: [0.1, 0.5, 0.5]\ncategories:\n  brick:\n    builder: external\n"
        "    colors: [teal, red]\n    external: {mesh: meshes/brick.stl}\n")
    monkeypatch.chdir(tmp_path)  # resolution must not depend on the working folder
    cat = load_catalog(str(tmp_path / "lib" / "cat.yaml"))
    builtin = load_catalog()
    assert set(builtin.categories) < set(cat.categories) and "brick" in cat.categories
    assert cat.colors["teal"] == (0.1, 0.5, 0.5) and "red" in cat.colors
    brick = cat.categories["brick"]
    assert brick.external["mesh"] == str(tmp_path / "lib" / "meshes" / "brick.stl")
    lo, hi = build_geometry(brick, {}, np.random.default_rng(0)).bounds()
    assert np.allclose(hi - lo, [0.1, 0.06, 0.04], atol=1e-6) and abs(lo[2]) < 1e-9


def test_missing_paths_are_errors_at_their_line(tmp_path):
    (tmp_path / "cat.yaml").write_text(
        "include: [builtin, other.yaml]\ncategories:\n  ghost:\n    builder: external\n    colors: [red]\n"
        "    external:\n      mesh: meshes/ghost.obj\n      collision: parts/\n")
    errs = _errors(lambda: load_catalog(str(tmp_path / "cat.yaml")))
    msgs = {(e.line, e.message.split(":")[0]) for e in errs}
    assert any(e.line == 1 and "other.yaml" in e.message for e in errs), errs
    assert any(e.line == 7 and "ghost.obj" in e.message for e in errs), errs
    assert any(e.line == 8 and "collision" in e.message for e in errs), msgs


def test_wrong_shared_data_root_is_one_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("REFSPATIAL_SHARED_DATA", str(tmp_path / "nowhere"))
    (tmp_path / "cat.yaml").write_text(
        "include: builtin\ncategories:\n" + "".join(
            f"  m{i}:\n    builder: external\n    colors: [red]\n    external: {{mesh: 'shared:ycb_sim/{i}/model.obj'}}\n"
            for i in range(4)))
    errs = _errors(lambda: load_catalog(str(tmp_path / "cat.yaml")))
    assert len(errs) == 1 and "REFSPATIAL_SHARED_DATA" in errs[0].message and "nowhere" in errs[0].message


def test_include_cycle_is_reported(tmp_path):
    (tmp_path / "a.yaml").write_text("include: b.yaml\ncategories: {}\n")
    (tmp_path / "b.yaml").write_text("include: a.yaml\ncategories: {}\n")
    errs = _errors(lambda: load_catalog(str(tmp_path / "a.yaml")))
    assert any("cycle" in e.message for e in errs)


def _recipe(tmp_path: Path, config: str) -> Path:
    p = tmp_path / "r.yaml"
    tpl = REPO / "recipes" / "templates" / "locate.yaml"
    p.write_text(f"name: t\nsources:\n  - kind: sim\n    config: {config}\nqa:\n  families:\n"
                 f"    locate: {{weight: 1.0, templates: ['{tpl}']}}\n")
    return p


def test_recipe_lint_checks_catalog_paths_relative_to_the_recipe(tmp_path):
    errs = lint_file(_recipe(tmp_path, "{catalog: missing.yaml}"))
    assert len(errs) == 1 and errs[0].line == 4 and str(tmp_path / "missing.yaml") in errs[0].message
    _mesh(tmp_path / "m.stl")
    (tmp_path / "mine.yaml").write_text("include: builtin\ncategories:\n  thing:\n    colors: [red]\n    external: {mesh: m.stl}\n")
    assert lint_file(_recipe(tmp_path, "{catalog: mine.yaml, external_prob: 0.5}")) == []
    errs = lint_file(_recipe(tmp_path, "{external_prob: 0.5}"))  # built-in catalog: no external meshes
    assert len(errs) == 1 and "no external meshes" in errs[0].message
    errs = lint_file(_recipe(tmp_path, "{renderer: povray}"))
    assert len(errs) == 1 and "unknown renderer" in errs[0].message


def test_laptop_screen_faces_its_stored_front():
    """The sheet showed the screen on the back of the lid (front "+x, the screen side" was wrong by eye)."""
    cat = load_catalog().categories["laptop"]
    for seed in range(3):
        geo = build_geometry(cat, cat.sample_dims(np.random.default_rng(seed)), np.random.default_rng(seed))
        lid = next(p for p in geo.parts if p.kind == "box" and p.rot is not None and abs(p.rot[0, 2]) > 0.3 and p.role == "body")
        screen = next(p for p in geo.parts if p.role == "screen")
        assert np.dot(screen.pos - lid.pos, cat.front) > 0.002  # the screen is on the front side of the lid
        assert lid.pos[0] < 0  # the lid leans back over the hinge, away from the keyboard


BASE = ("colors:\n  red: [0.8, 0.1, 0.1]\nmaterials:\n  plastic: {specular: 0.4}\ncategories:\n  thing:\n"
        "    builder: box\n    dims: {x: [0.1, 0.2], y: [0.1, 0.1], z: [0.1, 0.1]}\n")


def test_a_colour_or_material_given_as_a_list_is_a_recipe_error_with_its_line(tmp_path):
    """A nested list where a name belongs used to raise TypeError (unhashable list) out of the loader."""
    for bad, line in (("    colors: [[red]]\n", 9), ("    colors: [red]\n    materials: [[plastic]]\n", 10),
                      ("    colors: [red]\n    accent: [[0.1, 0.2, 0.3]]\n", 10), ("    colors: red\n", 9),
                      ("    colors: [red]\n    scale: [room]\n", 10)):
        p = tmp_path / f"cat{line}{len(bad)}.yaml"
        p.write_text(BASE + bad)
        errs = _errors(lambda: load_catalog(str(p)))
        assert len(errs) == 1 and errs[0].file == str(p) and errs[0].line == line, (bad, errs)


def test_bad_top_level_sections_and_material_values_are_recipe_errors(tmp_path):
    cases = {"colors: [red]\n": "colors must be a mapping",
             BASE.replace("{specular: 0.4}", "{specular: [0.4]}") + "    colors: [red]\n": "specular must be a number",
             BASE.replace("{specular: 0.4}", "{gloss: 0.4}") + "    colors: [red]\n": "unknown key 'gloss'",
             BASE.replace("[0.8, 0.1, 0.1]", "[.nan, 0.1, 0.1]") + "    colors: [red]\n": "colour 'red'",
             BASE.replace("[0.8, 0.1, 0.1]", "[1180591620717411303423, 0.1, 0.1]") + "    colors: [red]\n": "colour 'red'",
             BASE + "    colors: [red]\n    weight: [2]\n": "weight must be a number",
             BASE.replace("dims: {x: [0.1, 0.2], y: [0.1, 0.1], z: [0.1, 0.1]}", "dims: [1, 2]") + "    colors: [red]\n": "dims must be a mapping"}
    for i, (text, msg) in enumerate(cases.items()):
        p = tmp_path / f"c{i}.yaml"
        p.write_text(text)
        errs = _errors(lambda: load_catalog(str(p)))
        assert errs and any(msg in e.message for e in errs), (text, errs)
    p = tmp_path / "ok.yaml"
    p.write_text(BASE + "    colors: [red]\n")
    assert load_catalog(str(p)).categories["thing"].materials == ("plastic",)
