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
    assert r["objects"] == 8  # every annotated object was lifted
    assert all(g < 5.0 for g in r["gravity_error_deg"])  # RANSAC plane vs SUN's Rtilt
    assert r["relation_pairs"] >= 60
    # measured 87.7% (target 90%); 71.6% would mean the lifting regressed
    assert r["relation_agreement"] >= 0.85
    assert r["median_centre_error_cm"] < 75.0
    for f in r["frames"].values():
        f.validate()
        assert f.camera.gravity_known
        assert all(o.provenance["mask"] == "box_refined_by_depth" for o in f.objects)
        masks = [o.mask.decode() for o in f.objects]
        assert not np.any(np.sum(masks, axis=0) > 1)  # refined box masks are disjoint
