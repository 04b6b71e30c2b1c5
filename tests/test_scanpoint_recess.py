"""Answer points of box-only scan masks must not sit deep inside the box (sources/scan/surface.py)."""

from __future__ import annotations

from dataclasses import replace

from refspatial_gen.core.mask import answer_pixel
from refspatial_gen.graph import build_graph
from refspatial_gen.qa.verify_recess import check_recess as check_answer_point
from refspatial_gen.sources.scan import load_frame
from refspatial_gen.sources.scan.surface import REASON, WITHHELD


def test_scannet_tv_unit_cabinet_gets_no_point_in_its_niche(shared_data):
    """ScanNet scene0000_00/00102: the 'leftmost cabinet' box (1.5 m round a TV unit) had its answer point
    on the shelf over the TV, 0.7 m behind the box's front (round-3 audit, wrong)."""
    f = load_frame(shared_data / "scannet_scene0000_00", "00102")
    assert f.meta["truth"][REASON] == 1
    cab = next(o for o in f.objects if o.category == "cabinet" and o.id == 8)
    assert cab.provenance["answer_point"] == WITHHELD and cab.provenance["point_recess_m"] > 0.5
    pts = {n.object_id: n.point for n in build_graph(f).nodes}
    assert pts[8] is None
    # every other named object keeps its point, each on its box's face
    named = [o for o in f.objects if not o.provenance.get("distractor_only") and o.id != 8]
    assert named and all("answer_point" not in o.provenance for o in named)
    assert pts[13] is not None  # the sofa
    assert all(o.provenance["point_recess_m"] <= f.meta["max_point_recess"] for o in named)
    # verify's own check flags the old point and passes the others
    x, y = (int(v) for v in answer_pixel(cab.mask.decode()))
    assert check_answer_point(f, 8, x, y)
    for o in named:
        px = answer_pixel(o.mask.decode())
        assert check_answer_point(f, o.id, int(px[0]), int(px[1])) == []


def test_threshold_comes_from_the_frame(shared_data):
    """A looser limit keeps the cabinet's point: the rule is the recipe's threshold, not a fixed list."""
    f = load_frame(shared_data / "scannet_scene0000_00", "00102")
    cab = next(o for o in f.objects if o.id == 8)
    x, y = (int(v) for v in answer_pixel(cab.mask.decode()))
    loose = replace(f, meta={**f.meta, "max_point_recess": 2.0})
    assert check_answer_point(loose, 8, x, y) == []
