"""Text tidying: the fast string version must equal the rule it replaced (regex whitespace collapse, no space
before punctuation, stripped, first letter capitalised for sentences)."""

from __future__ import annotations

import random
import re

from refspatial_gen.qa.text import parse, render, tidy

_SPACES = re.compile(r"\s+")
_SPACE_PUNCT = re.compile(r"\s+([,.?!;:])")


def _rule(s: str, sentence: bool) -> str:
    s = _SPACE_PUNCT.sub(lambda m: m.group(1), _SPACES.sub(" ", s)).strip()
    return s[:1].upper() + s[1:] if s and sentence else s


def test_tidy_equals_the_regex_rule_on_fuzzed_text():
    rnd = random.Random(0)
    alphabet = list("ab ,.?!;:\t\n\r\x0b\x0c\x1c\x1f\xa0\u2000\u3000xY") + ["  ", " ."]
    for _ in range(20000):
        s = "".join(rnd.choice(alphabet) for _ in range(rnd.randint(0, 14)))
        for sentence in (True, False):
            assert tidy(s, sentence) == _rule(s, sentence), repr(s)


def test_split_whitespace_is_regex_whitespace():
    """tidy relies on str.split() splitting on exactly the characters regex \\s matches."""
    for c in map(chr, range(0x3100)):
        assert bool(re.match(r"\s", c)) == c.isspace(), hex(ord(c))


def test_rendered_text_is_tidy():
    seq = parse("  {Point to|Locate}   the cup [near the plate] , please ?")

    class Rng:
        def __init__(self) -> None:
            self.k = 0

        def integers(self, n: int) -> int:
            self.k += 1
            return self.k % n

        def random(self) -> float:
            return 0.1

    assert render(seq, lambda name: name, Rng()) == "Locate the cup near the plate, please?"
