"""Photos with geometric depth, checked against the truth data: people and vehicles lifted within their
category's height range, nothing resting on what cannot bear it, the photo's camera fitted to its objects.

Before the camera fit and occlusion-aware support, the shared COCO photos lifted people 0.2-3.7 m tall
and cars 0.2-2.8 m (17 of 31 people and vehicles outside the independent ranges of
../shared/tools/truth_figures.py), and stacked occluded objects on their occluders (car on car)."""

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.truth.sizes import can_bear, check_size

PEOPLE_AND_VEHICLES = ("person", "bicycle", "car", "motorcycle", "bus", "truck", "train")


def _frames(root, **over):
    import yaml

    from refspatial_gen.sources.image.annotations import load_collection
    from refspatial_gen.sources.image.source import _with_defaults, build_frame

    rec = yaml.safe_load(open("recipes/image.yaml", encoding="utf-8"))["sources"][0]["config"]
    cfg = _with_defaults({**rec, **over})
    coll = load_collection(root, cfg["format"], cfg["annotations"], cfg["images_dir"])
    out = []
    for iid in coll.ids():
        try:
            out.append(build_frame(coll, coll.images[iid], np.random.default_rng(0), cfg))
        except DropUnit:
            pass
    return out


def _figures(frames):
    lifted = [o for f in frames for o in f.objects if o.category in PEOPLE_AND_VEHICLES]
    ok = [o for o in lifted if check_size(o.category, o.box.size, dims=("height",)) is None]
    removed = sum(1 for f in frames for d in f.meta["dropped_object_list"]
                  if d["category"] in PEOPLE_AND_VEHICLES and d["reason"].startswith("size_"))
    return len(lifted), len(ok), removed


def test_street_photo_camera_is_fitted_to_its_people_and_vehicles(shared_data):
    """A street photo with cyclists, cars and people: the camera is fitted to them (consistent), every
    person and vehicle kept stands inside its height range (the far truck, lifted too short, is removed
    and counted), and nothing rests on a car or a person. (People and cars are left out as whole
    categories here: some of their instances are too small to keep, as before.)"""
    import yaml

    from refspatial_gen.sources.image.annotations import load_collection
    from refspatial_gen.sources.image.source import _with_defaults, build_frame

    rec = yaml.safe_load(open("recipes/image.yaml", encoding="utf-8"))["sources"][0]["config"]
    cfg = _with_defaults(rec)
    coll = load_collection(shared_data / "coco_tiny_train2017", "coco", None, None)
    f = build_frame(coll, coll.images["462565"], np.random.default_rng(0), cfg)
    ms = f.meta["metric_scale"]
    assert ms["source"] == "fit" and ms["status"] == "consistent" and ms["inliers"] >= 5, ms
    assert sum(o.category == "bicycle" for o in f.objects) >= 6
    assert f.meta["truth"].get("size_too_short", 0) >= 1
    for o in f.objects:
        if o.category in PEOPLE_AND_VEHICLES:
            assert check_size(o.category, o.box.size, dims=("height",)) is None, (o.category, o.box.size)
        if "rests_on" in o.provenance:
            assert can_bear(o.provenance["rests_on"]["category"], o.category)


@pytest.mark.slow
def test_coco_people_and_vehicles_within_their_height_range(shared_data):
    root = shared_data / "coco_tiny_train2017"
    # the root fix alone (camera fit + occlusion-aware support), no removal: >= 90 % in range (measured
    # 30 of 32; the old code had 14 of 31 within even wider ranges)
    n, ok, _ = _figures(_frames(root, size_check=False))
    print(f"\nwithout the size check: {ok}/{n} people and vehicles within their height range")
    assert n >= 15 and ok >= 0.9 * n
    # with the size check, what is still out of range is removed and counted
    frames = _frames(root)
    n2, ok2, removed = _figures(frames)
    truth = {}
    for f in frames:
        for k, v in f.meta["truth"].items():
            truth[k] = truth.get(k, 0) + v
    print(f"with it: {ok2}/{n2} in range, {removed} removed by size; frames {len(frames)}; truth counts {truth}")
    assert ok2 == n2 and n2 >= 15
    from refspatial_gen.sources.image.truthcheck import _overlap_share

    for f in frames:
        for i, a in enumerate(f.objects):  # solid things do not pass through each other
            for b in f.objects[i + 1:]:
                assert _overlap_share(a.box, b.box) <= 0.25, (f.frame_id, a.category, b.category)
        for o in f.objects:
            if "rests_on" in o.provenance:  # no object stands on one that cannot bear it
                assert can_bear(o.provenance["rests_on"]["category"], o.category), (f.frame_id, o.category)
            if "behind" in o.provenance:  # an occluded object stands on the ground, farther than its occluder
                occ = [p for p in f.objects if p.provenance["annotation_id"] == o.provenance["behind"]["annotation_id"]]
                for p in occ:
                    assert f.camera.world_to_cam(o.box.center)[0][2] > f.camera.world_to_cam(p.box.center)[0][2]
                assert abs(o.box.bottom_z) < 0.02


def test_boxes_never_pass_through_each_other(shared_data):
    """A bicycle half hidden behind a girl (562150) had its foot read as nearer than hers: its box ran
    through hers and "is the bicycle inside the person?" was answered yes. Lifted boxes sharing more
    than max_box_overlap of the smaller one's volume now remove the occluded one."""
    import yaml

    from refspatial_gen.sources.image.annotations import load_collection
    from refspatial_gen.sources.image.source import _with_defaults, build_frame
    from refspatial_gen.sources.image.truthcheck import _overlap_share

    rec = yaml.safe_load(open("recipes/image.yaml", encoding="utf-8"))["sources"][0]["config"]
    cfg = _with_defaults({**rec, "min_objects": 1})
    coll = load_collection(shared_data / "coco_tiny_train2017", "coco", None, None)
    f = build_frame(coll, coll.images["562150"], np.random.default_rng(0), cfg)
    assert f.meta["truth"].get("boxes_interpenetrate") == 1
    assert [d["category"] for d in f.meta["dropped_object_list"] if d["reason"] == "boxes_interpenetrate"] == ["bicycle"]
    objs = f.objects
    for i, a in enumerate(objs):
        for b in objs[i + 1:]:
            assert _overlap_share(a.box, b.box) <= cfg["max_box_overlap"]
