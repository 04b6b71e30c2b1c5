"""Per-instance material finish (issue 18 item 2): drawn within the catalog's per-material ranges,
recorded in provenance, different for different seeds, byte-identical for one seed."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from refspatial_gen.assets import load_catalog  # noqa: E402
from refspatial_gen.core.errors import RecipeError  # noqa: E402
from refspatial_gen.sources.sim.finish import FINISH_KEYS, draw_finish  # noqa: E402

SMALL = {"width": 160, "height": 120, "views": 1, "layouts": {"tabletop": 1.0}, "min_objects": 5, "max_objects": 7}


def test_catalog_ranges_keep_metal_shinier_than_wood_and_cloth_and_nothing_a_mirror():
    r = load_catalog().material_ranges
    for k in ("specular", "shininess"):
        assert r["metal"][k][0] > r["wood"][k][1] > r["fabric"][k][1]
        assert r["glass"][k][0] > r["plastic"][k][0]
    assert all(rr.get("reflectance", (0, 0))[1] <= 0.2 for rr in r.values())
    assert load_catalog().materials["metal"]["specular"] == pytest.approx(sum(r["metal"]["specular"]) / 2)


def test_draw_finish_stays_in_range_and_repeats_per_seed():
    ranges = load_catalog().material_ranges["metal"]
    a = [draw_finish(ranges, np.random.default_rng(1)) for _ in range(2)]
    b = draw_finish(ranges, np.random.default_rng(2))
    assert a[0] == a[1] and a[0] != b
    for f in a + [b]:
        for k in FINISH_KEYS:
            assert ranges[k][0] <= f[k] <= ranges[k][1]


def test_a_material_range_must_be_ordered_and_in_0_1(tmp_path):
    p = tmp_path / "cat.yaml"
    p.write_text("colors:\n  red: [0.8, 0.1, 0.1]\nmaterials:\n  plastic: {specular: [0.9, 0.2]}\ncategories:\n"
                 "  thing:\n    builder: box\n    dims: {x: [0.1, 0.2], y: [0.1, 0.1], z: [0.1, 0.1]}\n    colors: [red]\n")
    with pytest.raises(RecipeError, match="lo <= hi") as e:
        load_catalog(str(p))
    assert e.value.line == 4


def _finishes(seed: int):
    from refspatial_gen.sources.sim import generate

    frames, desc, sim = generate("sim:000001", np.random.default_rng(seed), SMALL, keep_scene=True)
    return frames, desc, sim


def test_finishes_differ_between_seeds_repeat_per_seed_and_reach_the_renderer():
    from refspatial_gen.sources.sim.looks import part_look

    cat = load_catalog()
    f1, d1, sim = _finishes(5)
    f1b, d1b, _ = _finishes(5)
    f2, d2, _ = _finishes(6)
    assert [o.finish for o in d1.objects] == [o.finish for o in d1b.objects]
    assert f1[0].rgb.tobytes() == f1b[0].rgb.tobytes()
    assert [o.finish for o in d1.objects] != [o.finish for o in d2.objects]
    by_id = {ob.id: ob for ob in f1[0].objects}
    assert by_id
    for k, o in enumerate(d1.objects):
        r = cat.material_ranges[o.material]
        assert all(r.get(key, (0, 1))[0] <= o.finish[key] <= r.get(key, (0, 1))[1] for key in FINISH_KEYS)
        if k + 1 in by_id:
            assert by_id[k + 1].provenance["finish"] == o.finish  # inspectable in the shards
        part = next(p for p in o.geometry.parts if p.visual)
        look = part_look(o, part, cat.colors, cat.materials)
        assert (look.specular, look.shininess, look.reflectance) == tuple(o.finish[key] for key in FINISH_KEYS)
    # two objects of one material get their own finish (not one value per material)
    same = {}
    for o in d1.objects + d2.objects:
        same.setdefault(o.material, set()).add(tuple(o.finish.values()))
    assert any(len(v) > 1 for v in same.values())
