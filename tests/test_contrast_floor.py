"""Contrast floor (graph/contrast.py, qa/verify_contrast.py; issue #15 audit round 4): an object a person
cannot make out against its surroundings (black on black, a dark speck, a featureless dark slab) is below
the floor, never named, counted in graph.meta["truth"]; verify re-checks it from the stored image and masks.

The main tests use only APIs that existed before the rule (build_graph, verify_sample, load_recipe), so they
fail on the old code by their assertions, not by an import."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from refspatial_gen.core.errors import RecipeErrors
from refspatial_gen.core.model import Sample
from refspatial_gen.graph import build_graph
from refspatial_gen.qa import generate_qa
from refspatial_gen.qa.verify import verify_sample
from refspatial_gen.qa.verify_truth import named_objects
from refspatial_gen.recipe import load_recipe
from refspatial_gen.sources.toy import TABLE
from tests.test_recog_floor import _scene

TOP = TABLE.top_z
CAN = 2  # the blue can of _scene()


def _paint(frame, oid: int, inside, around, ring: int = 14):
    """The frame with object `oid` painted `inside` (an RGB triple or a HxW->RGB function of the row) and the
    pixels within `ring` px around its mask painted `around`."""
    from scipy.ndimage import binary_dilation

    m = frame.object(oid).mask.decode()
    rgb = frame.rgb.copy()
    rgb[binary_dilation(m, iterations=ring) & ~m] = around
    rgb[m] = inside
    return dataclasses.replace(frame, rgb=rgb)


def _gradient(frame, oid: int, lo: int, hi: int) -> np.ndarray:
    """Per mask pixel an achromatic level from lo (top rows) to hi (bottom rows): shading across the object."""
    ys, _ = np.nonzero(frame.object(oid).mask.decode())
    t = (ys - ys.min()) / max(1, ys.max() - ys.min())
    v = np.rint(lo + (hi - lo) * t).astype(np.uint8)
    return np.stack([v, v, v], axis=1)


def test_black_object_on_black_surface_is_below_the_floor_and_never_named():
    f = _paint(_scene(), CAN, (12, 12, 13), (10, 10, 11))
    g = build_graph(f)
    assert g.node(CAN).attributes.get("below_floor") == "below_floor_contrast", g.node(CAN).attributes
    assert g.node(CAN).phrases == [] and g.node(CAN).point is None
    assert g.meta["truth"]["below_floor_contrast"] == 1
    assert g.meta["truth_floor"]["min_contrast_delta_e"] == 4.0 and g.meta["truth_floor"]["dark_lightness"] == 20.0


def test_clearly_visible_objects_are_not():
    g = build_graph(_scene())  # coloured, shaded cans and boxes on a wooden table
    assert "below_floor_contrast" not in (g.meta.get("truth") or {})
    f = _scene()
    g = build_graph(_paint(f, CAN, _gradient(f, CAN, 120, 230), (40, 40, 45)))  # a shaded white can on dark wood
    assert "below_floor" not in g.node(CAN).attributes and g.node(CAN).phrases


def test_dark_flat_slab_is_below_the_floor_unless_its_outline_stands_out():
    """A featureless dark object (no shading) on a mid-dark surface cannot be recognised (the black chair slab
    of audit item sim:000001/v0:01); the same flat dark object on a light table still reads by its outline,
    and a dark object with shading across it reads by its faces."""
    f = _scene()
    assert build_graph(_paint(f, CAN, (14, 14, 15), (60, 45, 35))).node(CAN).attributes.get("below_floor") == (
        "below_floor_contrast"
    )
    assert "below_floor" not in build_graph(_paint(f, CAN, (14, 14, 15), (200, 190, 170))).node(CAN).attributes
    shaded = _paint(f, CAN, _gradient(f, CAN, 10, 60), (60, 45, 35))
    assert "below_floor" not in build_graph(shaded).node(CAN).attributes


def test_dark_speck_is_below_the_floor():
    """A dark object above the pixel floor but under min_dark_px (the 197 px near-black toy block of audit item
    sim:000005/v0:02) is below the floor even on a light surface; a light one of the same size is not."""
    from refspatial_gen.core.mask import RLE

    f = _scene()
    ys, xs = np.nonzero(f.object(CAN).mask.decode())
    m = np.zeros((480, 640), bool)
    m[int(ys.mean()) - 8 : int(ys.mean()) + 9, int(xs.mean()) - 8 : int(xs.mean()) + 9] = True  # 289 px
    f = dataclasses.replace(
        f, objects=[dataclasses.replace(o, mask=RLE.encode(m)) if o.id == CAN else o for o in f.objects]
    )
    assert build_graph(_paint(f, CAN, _gradient(f, CAN, 5, 50), (200, 190, 170))).node(CAN).attributes.get(
        "below_floor"
    ) == ("below_floor_contrast")
    assert "below_floor" not in build_graph(_paint(f, CAN, (40, 70, 200), (200, 190, 170))).node(CAN).attributes


def test_thresholds_are_recipe_keys(tmp_path):
    f = _paint(_scene(), CAN, (12, 12, 13), (10, 10, 11))
    off = {"truth": {"min_contrast_delta_e": 0.0, "dark_lightness": 0.0}}
    assert "below_floor" not in build_graph(f, off).node(CAN).attributes
    r = tmp_path / "r.yaml"
    text = open("recipes/default.yaml").read().replace("recipes/templates", "templates")
    r.write_text(text + "graph:\n  truth:\n    min_contrast_delta_e: -1\n    dark_lightness: lots\n")
    (tmp_path / "templates").symlink_to((__import__("pathlib").Path("recipes/templates")).resolve())
    with pytest.raises(RecipeErrors) as e:
        load_recipe(r)
    msg = str(e.value)
    assert "r.yaml:" in msg and "min_contrast_delta_e" in msg and "dark_lightness" in msg


def test_verify_rejects_a_pair_naming_a_low_contrast_object():
    """Pairs generated on the clear picture name the can; stored with a picture where it is black on black
    (graph unchanged: the generator's floor is not what is tested), verify's own re-check fails them."""
    f = _scene()
    g = build_graph(f)
    cfg = load_recipe("recipes/default.yaml").qa
    qas = []
    for seed in range(12):
        qas += generate_qa([f], [g], np.random.default_rng(seed), cfg, truth={})
    naming = [copy.deepcopy(q) for q in qas if CAN in named_objects(q)]
    assert naming
    assert verify_sample(Sample("s", [f], [g], naming)) == []  # clean on the picture they were made for
    dark = _paint(f, CAN, (12, 12, 13), (10, 10, 11))
    reasons = [x["reason"] for x in verify_sample(Sample("s", [dark], [g], naming))]
    assert len(reasons) >= len(naming) and all("contrast" in r for r in reasons[: len(naming)]), reasons


def test_verify_measure_agrees_with_the_generator():
    """The two implementations (OpenCV vs CIE formulas and exact distance transforms) agree well within
    verify's tolerances on a shaded object."""
    from refspatial_gen.graph.contrast import lab_image, measure
    from refspatial_gen.qa.verify_contrast import DE_TOL, DETAIL_TOL, L_TOL, _measure

    f = _scene()
    for oid in (1, 2, 3, 4, 5):
        m = f.object(oid).mask.decode()
        a, b = measure(lab_image(f.rgb), m), _measure(f.rgb, m, 1.0)
        assert a is not None and b is not None
        assert abs(a.contrast - b[0]) < DE_TOL and abs(a.lightness - b[1]) < L_TOL and abs(a.detail - b[2]) < DETAIL_TOL
