"""The rewrite acceptance rules: each reason fires on the rewrite that breaks it, and good rewrites pass."""

import pytest

from refspatial_gen.rewrite import rules
from refspatial_gen.rewrite.check import Limits, answer_matches, assemble, body_reason
from refspatial_gen.rewrite.facts import split_suffix

VOCAB = frozenset(rules.NOUNS) | frozenset(rules.COLORS) | {"teddy bear", "table"}
ORIG = "Is the red cup to the left of the bowl?"
PH = ("the red cup", "the bowl")


def reason(new, original=ORIG, phrases=PH, words=(), answer="(A) yes"):
    return body_reason(original, new, phrases, words, VOCAB, answer, Limits())


@pytest.mark.parametrize("new", [
    "From where I stand, is the red cup to the left of the bowl?",
    "Looking at the photo, would you say the red cup sits on the left-hand side of the bowl?",
    "The red cup: is it left of the bowl?",
])
def test_faithful_rewrites_pass(new):
    assert reason(new) is None


@pytest.mark.parametrize("new,why", [
    ("", "empty"),
    ("Is the red cup\nleft of the bowl?", "not_one_line"),
    ("Is the red cup left of the bowl? " + "Really " * 60, "too_long"),
    ("Is the cup left of the bowl?", "phrase_missing"),
    ("Is the red cup left of the bowl, and is the bowl big?", "phrase_repeated"),
    ("Is the red cup left of the bowl and the blue plate?", "extra_object"),
    ("Is the bowl to the left of the red cup?", "order_changed"),
    ("Is the red cup left of the bowl near the lamp?", "extra_object"),
    ("Is the red cup to the right of the bowl?", "relation_changed"),
    ("Is the red cup not to the left of the bowl?", "relation_changed"),
    ("Is the red cup left of the bowl? Yes or no.", "leaked_answer"),
    ("Is the red cup 3 centimeters left of the bowl?", "number_changed"),
    ("Is the red cup to the left of the bowl? (A) yes (B) no", "format_text"),
    ("From its own left, is the red cup to the left of the bowl?", "perspective_changed"),
    ("is the red cup to the left of the bowl?", "unchanged"),
])
def test_each_rule_rejects_its_failure(new, why):
    assert reason(new) == why


def test_filter_words_must_survive_and_numbers_must_stay():
    o = "Point to the second apple from the left of the image."
    assert body_reason(o, "Show me the second apple counting from the left of the image.", (), ("apple",), VOCAB, "",
                       Limits()) is None
    assert body_reason(o, "Show me the second fruit counting from the left of the image.", (), ("apple",), VOCAB, "",
                       Limits()) == "word_missing"
    assert body_reason(o, "Show me the third apple from the left of the image.", (), ("apple",), VOCAB, "",
                       Limits()) == "relation_changed"
    q = "Point to an object on the table that is 1. left of the cup 2. near the bowl."
    assert body_reason(q, "Point to the object on the table that is left of the cup and near the bowl.",
                       ("the cup", "the bowl"), (), VOCAB, "", Limits()) is None  # enumeration markers may go


def test_perspective_phrases_are_kept():
    o = "Is the red cup above, from the image's perspective, the bowl?"
    assert reason("From the image's perspective, is the red cup above the bowl?", original=o) is None
    assert reason("Is the red cup above the bowl?", original=o) == "perspective_changed"


def test_a_choice_answer_named_in_the_body_is_a_leak():
    o = "Which is closer to the camera?"
    assert body_reason(o, "Is the bowl closer to the camera?", (), (), VOCAB, "(B) the bowl", Limits()) \
        == "extra_object"
    assert body_reason(o, "Which one, the second option, is closer to the camera?", (), (), VOCAB, "(B) second option",
                       Limits()) == "leaked_answer"


def test_answer_matches_parses_points_letters_and_numbers():
    assert answer_matches("[(0.412, 0.533)]", "[(0.412,0.533)]")
    assert not answer_matches("[(0.412, 0.533)]", "[(0.413, 0.533)]")
    assert answer_matches("(B)", "B")
    assert answer_matches("(B) yes", "(B)")
    assert not answer_matches("(B)", "(A)")
    assert answer_matches("35 centimeters", "35 centimeters.")
    assert not answer_matches("35 centimeters", "35 meters")
    assert not answer_matches("rotate left around 19.9 degrees", "rotate right around 19.9 degrees")
    assert not answer_matches("(A)", None)


def test_split_suffix_finds_choices_and_point_instructions():
    q = "Is the cup left of the bowl? (A) no (B) yes"
    assert split_suffix(q, {"kind": "choice", "options": ["no", "yes"]}) == ("Is the cup left of the bowl?", "(A) no (B) yes")
    assert split_suffix(q, {"kind": "choice", "options": ["yes", "no"]}) is None
    p = ("There is a jug left of the cup. Locate it. Answer with a list of tuples [(x1, y1),...] of normalized image "
         "coordinates between 0 and 1.")
    body, suffix = split_suffix(p, {"kind": "points"})
    assert body == "There is a jug left of the cup. Locate it." and suffix.startswith("Answer with a list of tuples")
    assert split_suffix("How tall is the cup?", {"kind": "number"}) == ("How tall is the cup?", "")
    assert split_suffix("Point to the cup.", {"kind": "points"}) is None


def test_assemble_tidies_and_reattaches_the_suffix():
    assert assemble(' "is the cup left of the bowl" ', "(A) no (B) yes", "Is x?") == \
        "Is the cup left of the bowl? (A) no (B) yes"
    assert assemble("how tall is the cup?", "", "How tall is x?") == "How tall is the cup?"
