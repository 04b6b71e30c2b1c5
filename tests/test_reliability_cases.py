"""Every reliability case (scripts/reliability.py): broken inputs built from the shared samples and mutated
recipes each end in a `file:line` / `path:` error or a counted drop — no traceback, hang or silent
acceptance. The table in docs/reliability.md is this run's output."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from relcases_inputs import input_cases  # noqa: E402
from relcases_recipes import recipe_cases  # noqa: E402
from relrun import classify  # noqa: E402

pytestmark = pytest.mark.slow


def test_every_broken_input_is_an_error_or_a_counted_drop(shared_data, tmp_path):
    bad = []
    for i, make in enumerate(input_cases()):
        case = make(shared_data)
        folder = tmp_path / f"c{i}"
        folder.mkdir()
        res = classify(case, folder)
        if not res.ok:
            bad.append(f"[{case.group}] {case.name}: {res.summary}")
    assert not bad, "\n".join(bad)


def test_every_recipe_mutation_is_refused_with_file_and_line(tmp_path):
    bad = []
    cases = recipe_cases()
    assert len(cases) >= 231
    for i, case in enumerate(cases):
        folder = tmp_path / f"r{i}"
        folder.mkdir()
        res = classify(case, folder)
        if not res.ok:
            bad.append(f"[{case.group}] {case.name}: {res.summary}")
    assert not bad, "\n".join(bad)
