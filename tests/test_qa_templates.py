"""Template language: text grammar, compiler errors as file:line: message, lint CLI, fuzzing."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from refspatial_gen.cli import main
from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.qa.config import load_qa_config
from refspatial_gen.qa.templates import compile_templates, load_template_file
from refspatial_gen.qa.text import TextSyntaxError, parse, placeholders, render
from refspatial_gen.tools.lint import lint_file
from refspatial_gen.yamlpos import load_yaml

REPO = Path(__file__).resolve().parents[1]


def test_text_grammar_synonyms_optional_placeholders():
    seq = parse("{Point to|Locate} the {cat} [in the image]{.|!} \\[x\\]")
    assert placeholders(seq) == {"cat"}
    seen = set()
    for k in range(60):
        s = render(seq, lambda n: "box", np.random.default_rng(k))
        assert s.endswith("[x]") and "the box" in s
        seen.add(s)
    # 2 verbs x optional x 2 endings
    assert len(seen) == 8
    assert all(s[0].isupper() for s in seen)


@pytest.mark.parametrize("bad", ["{unclosed", "[open", "closed]", "{not a name}", "a } b"])
def test_text_grammar_errors(bad):
    with pytest.raises(TextSyntaxError):
        parse(bad)


def test_default_templates_compile_with_steps_1_to_5():
    steps = set()
    for f in sorted((REPO / "recipes" / "templates").glob("*.yaml")):
        for t in load_template_file(f):
            assert 1 <= t.n_steps <= 5
            steps.add(t.n_steps)
    assert steps == {1, 2, 3, 4, 5}


GOOD = """\
templates:
  - name: t
    slots:
      cat: category
      rel: {type: relation, choices: [left, right]}
      a: anchor
    program:
      - {op: filter, category: cat}
      - {op: relate, relation: rel, anchor: a}
      - {op: locate}
    text:
      - "Point to the {cat} {rel} {a}."
"""

# each class of error: (replace this, with this, expected line, message fragment)
CASES = {
    "unknown relation": ("choices: [left, right]", "choices: [left, lefty]", 5, "unknown relation 'lefty'"),
    "unknown slot": ("anchor: a}", "anchor: b}", 9, "unknown slot 'b'"),
    "unknown slot in text": ("{rel} {a}.", "{rel} {z}.", 12, "unknown slot 'z' in text"),
    "wrong type": ("{op: filter, category: cat}", "{op: filter, category: a}", 8, "is a anchor slot"),
    "wrong type of value": ("      a: anchor\n", "      a: 7\n", 6, "must be a type name or a mapping"),
    "unknown op": ("{op: locate}", "{op: teleport}", 10, "unknown op 'teleport'"),
    "YAML syntax": ('      - "Point to', '      - ["Point to', 13, "YAML syntax"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_lint_reports_each_error_class_with_file_and_line(case, tmp_path, capsys):
    old, new, line, frag = CASES[case]
    assert old in GOOD
    p = tmp_path / "bad.yaml"
    p.write_text(GOOD.replace(old, new))
    rc = main(["recipes", "lint", str(p)])
    out = capsys.readouterr().out
    assert rc == 1
    lines = [ln for ln in out.splitlines() if ln.startswith(str(p) + ":")]
    assert lines, out
    assert any(re.match(rf"^{re.escape(str(p))}:{line}: .*{re.escape(frag)}", ln) for ln in lines), out


def test_step_count_out_of_range(tmp_path, capsys):
    t = GOOD.replace(
        "      - {op: locate}",
        textwrap.indent(
            textwrap.dedent("""\
        - {op: relate, relation: rel, anchor: b}
        - {op: relate, relation: rel, anchor: c}
        - {op: locate}"""),
            "      ",
        ),
    ).replace("      a: anchor\n", "      a: anchor\n      b: anchor\n      c: anchor\n")
    t = t.replace("{rel} {a}.", "{rel} {a}, {b} and {c}.")
    p = tmp_path / "long.yaml"
    p.write_text(t)
    assert main(["recipes", "lint", str(p)]) == 1
    out = capsys.readouterr().out
    assert re.search(rf"^{re.escape(str(p))}:\d+: step count 6 out of range", out, re.M), out


def test_good_template_lints_clean(tmp_path, capsys):
    p = tmp_path / "good.yaml"
    p.write_text(GOOD)
    assert main(["recipes", "lint", str(p)]) == 0
    assert main(["recipes", "lint", str(REPO / "recipes" / "default.yaml")]) == 0


def test_recipe_qa_section_errors_point_into_the_recipe(tmp_path):
    (tmp_path / "t.yaml").write_text(GOOD)
    r = tmp_path / "r.yaml"
    r.write_text("qa:\n  max_per_sample: 40\n  families:\n    locate: {weight: 1, templates: [t.yaml, missing.yaml]}\n")
    data, lines = load_yaml(r)
    with pytest.raises(RecipeErrors) as e:
        load_qa_config(data["qa"], str(r), lines)
    msgs = [str(x) for x in e.value.errors]
    assert any(m.startswith(f"{r}:2: ") and "<= 15" in m for m in msgs), msgs
    assert any(m.startswith(f"{r}:4: ") and "missing.yaml" in m for m in msgs), msgs


def test_relation_slot_needs_wording_for_its_form(tmp_path):
    p = tmp_path / "w.yaml"
    p.write_text(GOOD.replace("[left, right]", "[left, inside]").replace("{rel} {a}", "{rel.sup} {a}"))
    errs = lint_file(p)
    assert errs and any("no 'sup' wording" in e.message for e in errs)


# ------------------------------------------------------------------------------------ fuzzing
_words = st.sampled_from(
    [
        "name",
        "slots",
        "program",
        "text",
        "op",
        "relate",
        "filter",
        "locate",
        "left",
        "cat",
        "category",
        "anchor",
        "relation",
        "type",
        "choices",
        "{cat}",
        "{a|b}",
        "[x]",
        "in",
        "as",
        "weight",
        "between",
        "anchors",
        "measure",
        "quantity",
        "distance",
        "mark",
        "choose",
    ]
)
_scalars = st.one_of(
    _words, st.integers(-3, 9), st.floats(allow_nan=False, width=16), st.booleans(), st.none(), st.text(max_size=12)
)
_values = st.recursive(
    _scalars, lambda c: st.one_of(st.lists(c, max_size=4), st.dictionaries(_words, c, max_size=5)), max_leaves=25
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(_words, _values, max_size=6), st.lists(st.dictionaries(_words, _values, max_size=6), max_size=3))
def test_fuzzed_templates_never_raise(top, items):
    doc = dict(top)
    doc["templates"] = items
    errors: list[RecipeError] = []
    compile_templates(doc, "fuzz.yaml", {}, errors)
    for e in errors:
        assert isinstance(e, RecipeError) and str(e).startswith("fuzz.yaml:")


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=300))
def test_fuzzed_yaml_text_lints_without_traceback(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("fz") / "f.yaml"
    p.write_text(text, encoding="utf-8")
    for e in lint_file(p):
        assert isinstance(e, RecipeError) and str(e).startswith(str(p) + ":")


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_values)
def test_fuzzed_qa_sections_raise_only_recipe_errors(section):
    try:
        load_qa_config(section, str(REPO / "recipes" / "fuzz.yaml"), {})
    except (RecipeError, RecipeErrors):
        pass


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(sorted(CASES)), st.integers(0, 2**31 - 1))
def test_fuzzed_mutations_of_a_good_template(case, seed):
    rng = np.random.default_rng(seed)
    doc = yaml.safe_load(GOOD)
    t = doc["templates"][0]
    # delete or scramble a random key
    key = sorted(t)[int(rng.integers(len(t)))]
    if rng.random() < 0.5:
        del t[key]
    else:
        t[key] = [1, {"op": None}] if rng.random() < 0.5 or key == "name" else "x"
    errors: list[RecipeError] = []
    compile_templates(doc, "m.yaml", {}, errors)
    assert errors  # every mutation above breaks the template, and is reported, not raised


_recipe_words = st.sampled_from(
    [
        "name",
        "seed",
        "scenes",
        "sources",
        "kind",
        "toy",
        "weight",
        "qa",
        "families",
        "templates",
        "max_per_sample",
        "budget",
        "steps",
        "locate",
        "templates/locate.yaml",
        "shards",
        "samples_per_shard",
        "config",
        "point_slack",
    ]
)
_recipe_values = st.recursive(
    st.one_of(_recipe_words, st.integers(-5, 40), st.none(), st.booleans()),
    lambda c: st.one_of(st.lists(c, max_size=3), st.dictionaries(_recipe_words, c, max_size=4)),
    max_leaves=20,
)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(_recipe_words, _recipe_values, max_size=6))
def test_fuzzed_recipes_lint_without_traceback(tmp_path_factory, doc):
    d = tmp_path_factory.mktemp("rc")
    (d / "templates").mkdir()
    (d / "templates" / "locate.yaml").write_text((REPO / "recipes" / "templates" / "locate.yaml").read_text())
    p = d / "r.yaml"
    p.write_text(yaml.safe_dump(doc))
    for e in lint_file(p):
        assert isinstance(e, RecipeError) and str(e).startswith(str(p) + ":") or str(e).startswith(str(d))


def test_an_op_that_is_not_a_word_is_a_template_error_not_a_crash():
    """Hypothesis found `op: []` raising TypeError (unhashable) inside the compiler."""
    errors: list = []
    compile_templates({"templates": [{"program": [{"name": None, "op": []}]}]}, "t.yaml", {}, errors)
    assert any("unknown op" in str(e) for e in errors)
