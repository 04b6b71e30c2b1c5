"""Detection -> objects on real photos: with a detector and a segmenter replaced by test doubles that return
COCO's own boxes and masks, the unlabelled-photo path (perception) builds the same objects as the
annotated path (COCO instances), so the hand-off, lifting and captions are tested on real data; a photo
with no detection is dropped as `no_detections`."""

import shutil

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.perception.cache import array_hash
from tests.helpers.perception_fakes import FakeDetector, FakeSegmenter, install, model_folder, register_depth_estimator

N_IMAGES = 24
COMMON = {"depth": {"estimator": "geometric", "max_size_ratio": 3.0, "size_fallback": True}, "min_objects": 2}


@pytest.fixture
def coco(shared_data, tmp_path, monkeypatch):
    """(annotated folder, the same photos without annotations, test doubles' answers)."""
    pytest.importorskip("open3d")
    from refspatial_gen.sources.image.annotations import annotation_mask, load_collection
    from refspatial_gen.sources.image.source import decode_rgb

    src = shared_data / "coco_tiny_train2017"
    coll = load_collection(src, "coco")
    ids = [i for i in coll.ids() if not any(a.iscrowd for a in coll.images[i].annotations)][:N_IMAGES]
    photos = tmp_path / "photos" / "images"
    photos.mkdir(parents=True)
    dets, masks = {}, {}
    for iid in ids:
        rec = coll.images[iid]
        shutil.copy(rec.file, photos / rec.file.name)
        rgb = decode_rgb(rec.file)
        h = array_hash(rgb)
        dets[h] = []
        for a in rec.annotations:
            m, _ = annotation_mask(a, rec, rgb.shape[1], rgb.shape[0])
            dets[h].append((a.bbox, a.category, 0.9))
            masks[(h, tuple(float(x) for x in np.clip(a.bbox, 0, [rgb.shape[1], rgb.shape[0]] * 2)))] = m
    det, seg = FakeDetector(dets), FakeSegmenter(masks)
    model_folder(tmp_path / "models", "gd", "grounding-dino")
    model_folder(tmp_path / "models", "sam", "sam")
    install(monkeypatch, {"gd": det, "sam": seg})
    register_depth_estimator(monkeypatch)
    perception = {"models": str(tmp_path / "models"), "cache_dir": str(tmp_path / "cache"),
                  "filters": {"min_side": 1, "blur_threshold": 0.0, "max_clipped": 1.0, "min_brightness": 0.0,
                              "max_brightness": 255.0, "duplicate_distance": -1},
                  "detector": {"model": "gd", "vocabulary": "coco", "nms_iou": 1.0, "duplicate_iou": 1.0,
                               "max_detections": 100, "min_box_fraction": 0.0, "max_box_fraction": 1.0},
                  "segmenter": {"model": "sam", "min_box_fill": 0.0}}
    return src, tmp_path / "photos", [(i, coll.images[i].file.stem) for i in ids], perception, det


def _load(src, key, cfg):
    from refspatial_gen.run.plan import unit_rng
    from refspatial_gen.sources.image import ImageSource

    try:
        return ImageSource().load(key, unit_rng(0, key), {**cfg, "_input": str(src)})[0]
    except DropUnit as e:
        return e


def _objects(frame):
    return sorted((o.category, o.mask.counts, tuple(np.round(o.box.center, 6)), tuple(np.round(o.box.size, 6)))
                  for o in frame.objects)


def test_coco_boxes_through_perception_give_coco_objects(coco):
    from refspatial_gen.graph import build_graph
    from refspatial_gen.sources.image import ImageSource

    src, photos, ids, perception, det = coco
    keys = ImageSource().unit_keys({"perception": perception}, None, str(photos))
    assert keys == sorted(f"image:{stem}" for _, stem in ids)  # photo ids: file names without the suffix
    compared = same = 0
    for coco_id, stem in ids:
        a = _load(src, f"image:{coco_id}", {**COMMON, "format": "coco"})
        p = _load(photos, f"image:{stem}", {**COMMON, "perception": perception})
        if isinstance(a, DropUnit) or isinstance(p, DropUnit):
            assert isinstance(a, DropUnit) and isinstance(p, DropUnit), (stem, a, p)
            # a photo without annotations is, to a detector, a photo without detections
            assert a.reason == p.reason or (p.reason == "no_detections" and "0 usable" in a.detail), (stem, a, p)
            continue
        compared += 1
        same += _objects(a) == _objects(p)
        assert p.meta["intrinsics"] == a.meta["intrinsics"]
        assert p.meta["perception"]["models"]["detector"]["family"] == "grounding-dino"
        # captions on real pixels: the colour word is the graph's, ordinals follow the masks left to right
        g = build_graph(p, {})
        for o, n in zip(p.objects, g.nodes):
            assert o.attributes.get("color") == n.attributes.get("color")
            caps = o.provenance["captions"]
            xs = {q.id: np.nonzero(q.mask.decode())[1].mean() for q in p.objects if q.category == o.category}
            if any("leftmost" in c for c in caps):
                assert xs[o.id] == min(xs.values())
            if any("rightmost" in c for c in caps):
                assert xs[o.id] == max(xs.values())
    assert compared >= 5 and same == compared
    print(f"{compared} photos compared, {same} with identical objects")


def test_no_detection_is_a_counted_drop(coco):
    src, photos, ids, perception, det = coco
    det.answers.clear()
    p = _load(photos, f"image:{ids[0][1]}", {**COMMON, "perception": perception})
    assert isinstance(p, DropUnit) and p.reason == "no_detections"
