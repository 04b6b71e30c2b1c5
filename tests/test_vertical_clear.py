"""World above/below a person signs off (pre-audit round 5, sim/0/sim:000023/v0:11): over B resting at or above
its top, or beside B and clearly higher (graph/relations/vertical_clear.py; verify: qa/verify_vertical.py).

Each test fails on the code before the rule. Camera of test_graph_helpers: at y = -1 looking along +y.
"""

from __future__ import annotations

import pytest
from test_graph_helpers import TOP, box, check, scene

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.config import check_graph_section
from refspatial_gen.qa import lexicon
from refspatial_gen.qa.verify_world import Undecided, World

TRAY = (0.354, 0.239, 0.033)
BOOK = (0.24, 0.17, 0.03)
MOUSE = (0.107, 0.068, 0.035)


def verifier(frame, rel, *args, graph=None):
    try:
        return World(frame, graph or build_graph(frame)).holds(rel, *args)
    except Undecided:
        return None


def mouse_scene(mouse_z0: float, mouse_y: float = 0.20, book_y: float = 0.20):
    """tray (1) at the front, a thin book (2) behind it, the mouse (3) at mouse_z0."""
    return scene(
        ("tray", "orange", box(0.0, -0.12, TRAY)),
        ("book", "white", box(0.0, book_y, BOOK)),
        ("computer mouse", "blue", box(0.0, mouse_y, MOUSE, z0=mouse_z0)),
    )


def test_mouse_on_a_book_beside_the_tray_is_neither_above_nor_below_it():
    """The audit item: the mouse's bottom (the book's top, 3 cm) just at the tray's rim (3.3 cm), the book
    behind the tray. Old rule: a resting "stack" -> "physically above the tray" = yes."""
    fr, g = mouse_scene(TOP + BOOK[2])
    check(fr, g, "above_world", (3, 1), None)
    check(fr, g, "below_world", (1, 3), None)
    assert verifier(fr, "above_world", 3, 1) is None
    assert verifier(fr, "below_world", 1, 3) is None
    assert build_graph(fr, {"free_space": False}).meta["truth"]["vertical_beside_margin"] >= 1
    # the mouse on the book it rests on is still above it (over it: footprints overlap)
    check(fr, g, "above_world", (3, 2), True)
    assert verifier(fr, "above_world", 3, 2) is True


def test_beside_and_clearly_higher_is_above():
    """Beside the tray on a shelf 30 cm up (gap >= max(0.10 m, half the tray's height)): above; at 8 cm, inside
    the clear margin: undecided."""
    fr, g = mouse_scene(TOP + 0.30, book_y=0.45)
    check(fr, g, "above_world", (3, 1), True)
    check(fr, g, "below_world", (1, 3), True)
    assert verifier(fr, "above_world", 3, 1) is True
    assert verifier(fr, "below_world", 1, 3) is True
    fr, g = mouse_scene(TOP + TRAY[2] + 0.08, book_y=0.45)
    check(fr, g, "above_world", (3, 1), None)
    assert verifier(fr, "above_world", 3, 1) is None


def test_over_the_tray_resting_at_its_rim_is_above():
    """The same mouse over the tray, its bottom at the tray's top: above (a resting stack, as before)."""
    fr, g = mouse_scene(TOP + TRAY[2], mouse_y=-0.12)
    check(fr, g, "above_world", (3, 1), True)
    assert verifier(fr, "above_world", 3, 1) is True


def test_clear_margin_is_a_recipe_threshold():
    """graph: thresholds: vertical_clear_margin lowered to 1 mm and the share to 0 lets the beside case through
    again (both in the generator and in verify, which reads the graph's thresholds); a bad value is a recipe
    error."""
    th = {"vertical_clear_margin": 0.0, "vertical_clear_share": 0.0}
    fr, _ = mouse_scene(TOP + BOOK[2] + 0.004)
    graph = build_graph(fr, {"free_space": False, "thresholds": th})
    above = [f for f in graph.facts if f.relation == "above_world" and set(f.args) == {1, 3}]
    assert above and above[0].holds is False  # stored lower id first: the tray is below the mouse
    assert verifier(fr, "above_world", 3, 1, graph=graph) is True
    errors: list[RecipeError] = []
    check_graph_section({"thresholds": {"vertical_clear_margin": "ten cm"}}, "r.yaml", {}, errors)
    assert errors and "vertical_clear_margin" in str(errors[0])


@pytest.mark.parametrize("rel", ["above_world", "below_world"])
def test_world_wording_says_higher_or_lower_not_over(rel):
    """ "physically above the tray" reads as over it; beside it and higher is only "higher than". The yes/no and
    choice wording ("prep") says higher/lower, never the bare "above"/"below"."""
    from test_qa_language import _expansions

    from refspatial_gen.qa.text import parse

    word = "higher" if rel == "above_world" else "lower"
    for text in _expansions(parse(lexicon.RELATION_FORMS[rel]["prep"])):
        assert word in text and "above" not in text and "below" not in text, text
