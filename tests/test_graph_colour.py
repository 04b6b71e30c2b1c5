"""The colour namer on real-looking pixels: shading, colours between basic terms, people and animals.

Each case failed on the HSV-hue namer it replaced (issue 15: "a teal car 'black', a yellow taxi 'brown',
'the black person'")."""

from __future__ import annotations

import numpy as np
import pytest

from refspatial_gen.graph.colour import colour_shares, colour_word, never_coloured


def shaded(rgb, n=3000, lit=(0.45, 1.0), seed=0):
    """A matte patch of one colour under shading: linear RGB scaled by a factor per pixel, plus noise."""
    r = np.random.default_rng(seed)
    lin = (np.array(rgb, float) / 255.0) ** 2.2
    k = r.uniform(*lit, n)[:, None]
    px = (lin[None] * k) ** (1 / 2.2) * 255.0 + r.normal(0, 2.0, (n, 3))
    return np.clip(np.rint(px), 0, 255).astype(np.uint8)


def test_yellow_taxi_under_shading_is_yellow_not_brown():
    taxi = shaded((245, 195, 25), lit=(0.25, 1.0))  # half the body in shadow
    assert colour_word(taxi) == ("yellow", "pixels")


def test_teal_is_never_black_and_gets_no_basic_word():
    teal = shaded((0, 128, 128), lit=(0.4, 1.0))  # the XKCD "teal" family: between blue and green
    word, how = colour_word(teal)
    assert word is None and how == "margin"
    assert colour_shares(teal).get("black", 0.0) < 0.05


@pytest.mark.parametrize(
    "rgb, word",
    [
        ((190, 25, 30), "red"),
        ((30, 70, 180), "blue"),
        ((35, 130, 45), "green"),
        ((20, 20, 22), "black"),
        ((105, 65, 30), "brown"),
    ],
)
def test_clear_colours_keep_their_word_under_shading(rgb, word):
    assert colour_word(shaded(rgb)) == (word, "pixels")


@pytest.mark.parametrize("cat", ["person", "Man", "woman", "people", "dog", "horse", "Bird", "giraffe", "cats"])
def test_people_and_animals_never_get_a_colour(cat):
    red = shaded((190, 25, 30))
    assert never_coloured(cat)
    assert colour_word(red, "red", cat) == (None, "person_or_animal")


def test_things_still_get_colours():
    assert not never_coloured("car") and not never_coloured("teddy bear") and not never_coloured("cup")
    assert colour_word(shaded((190, 25, 30)), None, "car")[0] == "red"


def test_margin_threshold_decides():
    half = np.concatenate([shaded((190, 25, 30), 1000), shaded((30, 70, 180), 800, seed=1)])
    assert colour_word(half) == (None, "margin")  # 55 % red against 45 % blue
    assert colour_word(half, min_share=0.5, margin=0.05)[0] == "red"
    assert colour_word(half, "red")[0] == "red"  # the known colour settles a winner held back by the margin
    assert colour_word(half, "blue")[0] is None  # ... never a loser
