"""The plug-in registries: one Registry class for every kind, relation ids and uses read from the relation
registry (tied to the spec, the wording and the ops), and no stage importing a later one."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from refspatial_gen.core.registry import Registry, UnknownName
from refspatial_gen.graph.relations import REGISTRY, SPEC_31, ids_by_use, template_relations
from refspatial_gen.qa import lexicon
from refspatial_gen.qa.ops import ANSWER_TYPES, MARKS, OPS, SET, allowed_relations

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "refspatial_gen"


def test_registry_lazy_entries_listing_and_unknown_names() -> None:
    r: Registry[object] = Registry("widget")
    r.add("json", "json:dumps")  # imported on first use
    r.add("obj", 42)
    assert r.names() == ["json", "obj"] and "json" in r and len(r) == 2
    import json

    assert r.get("json") is json.dumps and r["obj"] == 42
    with pytest.raises(UnknownName, match=r"unknown widget 'nope' \(known: json, obj\)"):
        r.get("nope")
    with pytest.raises(ValueError, match="registered twice"):
        r.add("obj", 1)
    r.remove("obj")
    assert r.names() == ["json"]


def test_every_plugin_kind_uses_the_registry() -> None:
    from refspatial_gen.depth import ESTIMATORS, estimator_names
    from refspatial_gen.sources import SOURCES, source_names
    from refspatial_gen.sources.scan.readers import READERS

    for reg in (SOURCES, READERS, ESTIMATORS, REGISTRY, OPS):
        assert isinstance(reg, Registry) and len(reg) > 0
    assert source_names() == sorted(SOURCES.names()) and estimator_names() == sorted(ESTIMATORS.names())
    with pytest.raises(KeyError, match="unknown source 'nope'"):
        SOURCES.get("nope")


def test_relation_ids_come_from_the_registry() -> None:
    """The spec's 31 are registered; templates may name those plus the extras with a QA use; every relation
    templates may name has default wording; the op relation lists are the registry's uses."""
    assert len(SPEC_31) == 31 and all(r in REGISTRY for r in SPEC_31)
    assert template_relations() == SPEC_31 + ("on", "next_to")
    for rid in template_relations():
        if REGISTRY[rid].qa:
            assert lexicon.RELATION_FORMS.get(rid, {}).get("prep"), rid
    assert set(lexicon.RELATION_FORMS) <= set(REGISTRY.names())
    assert set(ids_by_use("ordered")) == {
        "left",
        "right",
        "front",
        "behind",
        "above_world",
        "below_world",
        "above_image",
        "below_image",
        "tall",
        "short",
        "big",
        "small",
        "wide",
        "thin",
    }
    assert set(ids_by_use("anchored")) == {"close", "far"}
    assert set(allowed_relations(OPS["relate"])) == set(ids_by_use("ordered") + ids_by_use("pairwise"))


def test_every_op_declares_itself() -> None:
    for name in OPS.names():
        op = OPS[name]
        assert op.name == name and op.doc and op.out in (*ANSWER_TYPES, SET, MARKS), name
        assert all(u in ("ordered", "pairwise", "anchored") for u in op.relation_uses)
        assert ("relation" in op.args) == bool(op.relation_uses), name


def test_default_relation_choices_do_not_depend_on_the_hash_seed(tmp_path: Path) -> None:
    """A relation slot without `choices:` takes the ops' allowed relations; their order feeds the search's
    shuffle, so it must not follow a set's string-hash order (which changes with PYTHONHASHSEED). Failed
    before the compiler kept the ops' order."""
    code = textwrap.dedent("""
        from refspatial_gen.qa.templates import compile_templates
        doc = {"templates": [{"name": "t", "slots": {"a": "anchor", "rel": "relation"},
                              "program": [{"op": "relate", "relation": "rel", "anchor": "a"}, {"op": "locate"}],
                              "text": ["Point to the object {rel} {a}."]}]}
        errors = []
        print(compile_templates(doc, "t.yaml", {}, errors)[0].slots["rel"].choices, errors)
    """)
    outs = set()
    for seed in ("1", "2", "3"):
        env = {**os.environ, "PYTHONHASHSEED": seed, "PYTHONPATH": str(ROOT)}
        outs.add(
            subprocess.run(
                [sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, check=True
            ).stdout
        )
    assert len(outs) == 1, outs


# stage -> the refspatial_gen packages it may import (module level and inside functions)
LAYERS = {
    "core": {"core"},
    "graph": {"core", "graph", "schema", "truth"},
    "qa": {"core", "graph", "qa", "schema", "truth", "yamlpos"},
}
ALLOWED = {("qa/bench.py", "sources")}  # the QA bench builds toy scenes to time the engine on


def _imports(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("refspatial_gen."):
            out.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("refspatial_gen.")}
        elif (
            isinstance(node, ast.Call)
            and getattr(node.func, "attr", "") == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and str(node.args[0].value).startswith("refspatial_gen.")
        ):
            out.add(str(node.args[0].value).split(".")[1])  # a hidden import counts like any other
    return out


def test_stages_import_only_earlier_stages() -> None:
    bad = []
    for stage, allowed in LAYERS.items():
        for path in sorted((PKG / stage).rglob("*.py")):
            rel = str(path.relative_to(PKG))
            for mod in _imports(path) - allowed:
                if (rel, mod) not in ALLOWED:
                    bad.append(f"{rel} imports refspatial_gen.{mod}")
    assert not bad, bad


def test_recipe_loads_qa_without_hidden_imports() -> None:
    src = (PKG / "recipe.py").read_text()
    assert "importlib" not in src and "refspatial_gen.qa" in src
    assert "sources" not in _imports(PKG / "shards" / "writer.py")
    assert not (PKG / "shards" / "testing.py").exists()  # test support lives beside the toy source
