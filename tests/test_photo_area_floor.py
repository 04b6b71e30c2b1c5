"""Photo area floor (graph/visibility.py `min_photo_area_fraction`, qa/verify_truth.py): on a photo (an
estimated metric scale, no occlusion estimate) an object under 0.4 % of the image is never named (audit round
3: a toilet seen as a sliver behind a door frame, a chair glimpsed through a far doorway); verify agrees."""

from __future__ import annotations

import dataclasses

import numpy as np

from refspatial_gen.core.mask import RLE
from refspatial_gen.graph import build_graph
from refspatial_gen.graph.visibility import PHOTO_SMALL, Floor
from refspatial_gen.qa.verify_truth import below_floor, check_truth, named_objects
from tests.test_recog_floor import _many, _scene, _with, cfg  # noqa: F401  (cfg: a fixture)


def _small_can(photo: bool):
    """The scene with can 2 seen as a compact 28x28 px patch (784 px: over the 150 px floor, under 0.4 % of
    640x480 = 1229 px), on a photo or not."""
    f = _scene()
    m = next(o for o in f.objects if o.id == 2).mask.decode()
    ys, xs = np.nonzero(m)
    cy, cx = int(ys.mean()), int(xs.mean())
    win = np.zeros_like(m)
    win[cy - 14 : cy + 14, cx - 14 : cx + 14] = True
    f = _with(f, 2, mask=RLE.encode(m & win))
    if photo:
        f = dataclasses.replace(f, meta={**f.meta, "metric_scale": {"reliable": True, "source": "test"}})
    return f


def test_small_object_of_a_photo_is_below_the_floor_but_not_in_a_rendered_scene():
    assert Floor().min_photo_area_fraction == 0.004
    f = _small_can(photo=True)
    px = int(next(o for o in f.objects if o.id == 2).mask.decode().sum())
    assert 150 <= px < 0.004 * 640 * 480
    g = build_graph(f)
    assert g.node(2).attributes["below_floor"] == PHOTO_SMALL and g.node(2).phrases == []
    assert g.meta["truth"][PHOTO_SMALL] == 1
    assert g.meta["truth_floor"]["min_photo_area_fraction"] == 0.004
    assert "of the photo" in below_floor(f, g.meta["truth_floor"])[2]
    plain = build_graph(_small_can(photo=False))  # a rendered scene: the pixel floor alone decides
    assert "below_floor" not in plain.node(2).attributes


def test_verify_flags_a_pair_naming_a_small_object_of_a_photo(cfg):  # noqa: F811
    """A pair generated on the rendered frame names the small can; stored as a photo, verify rejects it."""
    f, fp = _small_can(photo=False), _small_can(photo=True)
    g = build_graph(f)
    gp = dataclasses.replace(g, meta={**g.meta, "truth_floor": build_graph(fp).meta["truth_floor"]})
    pairs, _ = _many(f, g, cfg, n=6)
    naming = [q for q in pairs if 2 in named_objects(q)]
    assert naming
    for q in naming:
        assert any("below the visibility floor" in r for r in check_truth(q, {f.frame_id: fp}, {f.frame_id: gp}))
    photo_pairs, _ = _many(fp, build_graph(fp), cfg, n=6)
    assert photo_pairs and not any(2 in named_objects(q) for q in photo_pairs)
