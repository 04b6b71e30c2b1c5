"""SUN RGB-D frames as plain photos (provided depth + 2D boxes): lifted objects vs ground-truth 3D boxes.

Prints the two figures reported in docs/image.md: the median centre error and the agreement of pairwise
relations (left/front/above/bigger/taller/wider) on pairs where both sides are decided."""

import numpy as np
import pytest

pytest.importorskip("open3d")


def test_sunrgbd_lifting_vs_ground_truth(shared_data):
    from refspatial_gen.sources.image.evaluate import compare_sunrgbd

    r = compare_sunrgbd(shared_data / "sunrgbd")
    print(f"\nSUN RGB-D ({r['objects']} objects in {len(r['frames'])} frames): median centre error "
          f"{r['median_centre_error_cm']} cm (mean {r['mean_centre_error_cm']} cm); relation agreement "
          f"{100 * r['relation_agreement']:.1f}% on {r['relation_pairs']} decided pairs; "
          f"gravity error {r['gravity_error_deg']} deg")
    for rel, v in r["by_relation"].items():
        print(f"  {rel}: {v['agree']}/{v['decided_both']}")
    for o in r["per_object"]:
        print("  ", o)
    # 7 of the 8 annotated objects are lifted; the lamp of 000001 (white shade, thin stem: ~180 of its
    # 5300 box pixels have depth on it) is dropped with a reason instead of being lifted from the wall
    assert r["objects"] == 7
    dropped = [d for f in r["frames"].values() for d in f.meta["dropped_object_list"]]
    assert [(d["category"], d["reason"]) for d in dropped] == [("lamp", "too_small")]
    assert all(g < 5.0 for g in r["gravity_error_deg"])  # RANSAC plane vs SUN's Rtilt
    assert r["relation_pairs"] >= 50
    # measured 96.4% (53 of 55; target 90%); before depth layering + amodal completion: 87.6%
    assert r["relation_agreement"] >= 0.93
    assert r["median_centre_error_cm"] < 35.0  # measured 25.0 cm (was 58.8 cm)
    by_cat = {(o["image"], o["category"]): o["error_cm"] for o in r["per_object"]}
    assert by_cat[("000001", "night_stand")] < 50.0  # its box is mostly the bed in front (was 225 cm)
    for f in r["frames"].values():
        f.validate()
        assert f.camera.gravity_known
        assert all(o.provenance["mask"] == "box_refined_by_depth" for o in f.objects)
        masks = [o.mask.decode() for o in f.objects]
        assert not np.any(np.sum(masks, axis=0) > 1)  # refined box masks are disjoint
