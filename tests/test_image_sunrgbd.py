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
    for iid, v in r["per_frame"].items():
        print(f"  frame {iid}: {v}")
        # every frame on its own, not only the pool (a two-object frame has 5-6 decided pairs)
        assert v["relation_agreement"] >= 0.93 and v["gravity_error_deg"] < 5.0, (iid, v)
    # 7 or 8 of the 8 annotated objects are lifted: the lamp of 000001 (white shade, thin stem: ~180 of
    # its 5300 box pixels have depth on it) is lifted from those pixels or dropped with a reason, never
    # lifted from the wall behind
    assert r["objects"] >= 7
    dropped = [d for f in r["frames"].values() for d in f.meta["dropped_object_list"]]
    assert [(d["category"], d["reason"]) for d in dropped] in ([], [("lamp", "too_small")])
    lamp = [o for o in r["per_object"] if o["category"] == "lamp"]
    assert all(o["error_cm"] < 40.0 for o in lamp)
    assert all(g < 5.0 for g in r["gravity_error_deg"])  # RANSAC plane vs SUN's Rtilt
    assert r["relation_pairs"] >= 50
    # measured 96.4% (53 of 55; target 90%); before depth layering + amodal completion: 87.6%
    assert r["relation_agreement"] >= 0.93
    assert r["median_centre_error_cm"] < 35.0  # measured 23.7 cm (was 58.8 cm)
    by_cat = {(o["image"], o["category"]): o["error_cm"] for o in r["per_object"]}
    assert by_cat[("000001", "night_stand")] < 50.0  # its box is mostly the bed in front (was 225 cm)
    for f in r["frames"].values():
        f.validate()
        assert f.camera.gravity_known
        assert all(o.provenance["mask"] == "box_refined_by_depth" for o in f.objects)
        masks = [o.mask.decode() for o in f.objects]
        assert not np.any(np.sum(masks, axis=0) > 1)  # refined box masks are disjoint


def test_gravity_is_found_on_every_seed(shared_data):
    """RANSAC from random point triples missed the floor (19 % of the points) about one seed in six and
    took a bed cover or a table for the floor: 22.6 degrees off on an unseen SUN RGB-D frame, up to 9
    degrees on 000002. One-point hypotheses (a point and its local normal) and the refinement on all
    levels and walls keep every seed within 5 degrees of SUN's Rtilt."""
    import json

    from PIL import Image

    from refspatial_gen.sources.image.evaluate import F_SUN
    from refspatial_gen.sources.image.gravity import estimate_gravity

    for sid in ("000001", "000002"):
        d = shared_data / "sunrgbd" / sid
        a = json.loads((d / "annotation.json").read_text())
        K = np.array(a["K"])
        depth = np.asarray(Image.open(d / "depth.png"), float) / 1000.0
        vs, us = np.mgrid[0:depth.shape[0]:3, 0:depth.shape[1]:3]
        z = depth[::3, ::3]
        ok = z > 0
        pts = np.stack([(us[ok] + 1 - K[0, 2] - 0.5) * z[ok] / K[0, 0], (vs[ok] + 1 - K[1, 2] - 0.5) * z[ok] / K[1, 1],
                        z[ok]], axis=1)
        up_gt = F_SUN @ np.array(a["Rtilt"]).T @ np.array([0.0, 0.0, 1.0])
        errs = []
        for seed in range(12):
            g = estimate_gravity(pts, np.random.default_rng(seed), np.array([0.0, -1.0, 0.0]), 40.0)
            errs.append(float(np.degrees(np.arccos(np.clip(g.up_cam @ up_gt, -1, 1)))))
        print(sid, "gravity error over 12 seeds: max", round(max(errs), 2), "median", round(float(np.median(errs)), 2))
        assert max(errs) < 5.0, (sid, errs)
