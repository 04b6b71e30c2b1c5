"""Captions: ordinals counted from the nearer side and never across a tie, hierarchical order, colour from
the graph's own namer."""

import numpy as np

from refspatial_gen.perception.captions import colour_of, hierarchical, ordinal_captions


def test_ordinals_left_to_right_from_the_nearer_side():
    cats = ["cup", "cup", "cup", "cup", "bowl"]
    xs = [300.0, 10.0, 150.0, 220.0, 50.0]
    dists = [1.0, 2.0, 3.0, 4.0, 1.0]
    caps = ordinal_captions(cats, xs, dists, 400)
    assert "the leftmost cup" in caps[1] and "the second cup from the left" in caps[2]
    assert "the second cup from the right" in caps[3] and "the rightmost cup" in caps[0]
    assert "the nearest cup" in caps[0] and "the farthest cup" in caps[3] and "the second nearest cup" in caps[1]
    assert "the second farthest cup" in caps[2]
    assert caps[4] == []  # the only bowl needs no ordinal


def test_no_ordinal_across_a_tie():
    caps = ordinal_captions(["cup", "cup", "cup"], [100.0, 103.0, 300.0], [1.0, 2.0, 2.05], 400)
    assert not any("left" in c or "right" in c for cs in caps for c in cs)  # 3 px apart: too close to call
    assert not any("near" in c or "far" in c for cs in caps for c in cs)  # 5 cm apart


def test_hierarchical_coarse_to_fine():
    assert hierarchical("cup", {"color": "red", "material": "ceramic"}, ["the leftmost cup"], False) == [
        "cup", "the red ceramic cup", "the leftmost cup"]
    assert hierarchical("bowl", {}, [], True) == ["the bowl"]


def test_colour_words_come_from_the_graph_namer(toy_frame):
    from refspatial_gen.graph.colour import colour_word, image_white, mask_pixels

    white = image_white(toy_frame.rgb)
    for o in toy_frame.objects:
        m = o.mask.decode()
        ys, xs = np.nonzero(m)
        crop = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
        px = mask_pixels(toy_frame.rgb[crop], m[crop])
        assert colour_of(toy_frame.rgb, m) == colour_word(px, white=white)[0]
    red = np.zeros((40, 40, 3), np.uint8)
    red[..., 0] = 210
    assert colour_of(red, np.ones((40, 40), bool)) == "red"
