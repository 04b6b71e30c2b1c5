"""COCO mask codecs: compressed RLE round trip, agreement with real panoptic PNGs and COCO's own areas."""

import json

import numpy as np

from refspatial_gen.core.mask import RLE
from refspatial_gen.sources.image.rle import (
    box_mask, decode_counts_string, encode_counts_string, polygons_to_mask, rle_from_coco,
)


def test_compressed_rle_round_trip(rng):
    for _ in range(20):
        h, w = int(rng.integers(1, 40)), int(rng.integers(1, 40))
        m = rng.random((h, w)) < rng.uniform(0.05, 0.95)
        runs = list(RLE.encode(m).counts)
        s = encode_counts_string(runs)
        assert decode_counts_string(s) == runs
        assert np.array_equal(rle_from_coco({"size": [h, w], "counts": s}, h, w).decode(), m)


def test_rle_size_mismatch_is_rejected():
    runs = list(RLE.encode(np.ones((4, 5), bool)).counts)
    try:
        rle_from_coco({"size": [5, 4], "counts": runs}, 4, 5)
    except ValueError as e:
        assert "does not match" in str(e)
    else:
        raise AssertionError("a wrong-size RLE was accepted")


def test_compressed_rle_matches_panoptic_png(shared_data):
    """The detection-format RLE strings of the panoptic sample decode to exactly the PNG's segments."""
    import cv2

    root = shared_data / "coco_panoptic_sample"
    det = json.loads((root / "panoptic_coco_detection_format.json").read_text())
    pan = json.loads((root / "panoptic_examples.json").read_text())
    seg_of = {}
    for a in pan["annotations"]:
        png = cv2.imread(str(root / "panoptic_examples" / a["file_name"]))[..., ::-1].astype(np.int64)
        ids = png[..., 0] + 256 * png[..., 1] + 65536 * png[..., 2]
        for s in a["segments_info"]:
            seg_of[(a["image_id"], s["category_id"], s["area"])] = ids == s["id"]
    checked = 0
    for a in det["annotations"]:
        h, w = a["segmentation"]["size"]
        m = rle_from_coco(a["segmentation"], h, w).decode()
        ref = seg_of.get((a["image_id"], a["category_id"], a["area"]))
        if ref is not None:
            assert np.array_equal(m, ref)
            checked += 1
    assert checked >= 40


def test_polygon_area_matches_coco(shared_data):
    d = json.loads((shared_data / "coco_tiny_train2017" / "instances.json").read_text())
    size = {i["id"]: (i["height"], i["width"]) for i in d["images"]}
    rel = []
    for a in d["annotations"][:150]:
        if a["iscrowd"] or a["area"] < 500:
            continue
        h, w = size[a["image_id"]]
        rel.append((polygons_to_mask(a["segmentation"], h, w).sum() - a["area"]) / a["area"])
    # cv2.fillPoly also fills pixels the outline crosses: about 4% more than COCO's polygon areas
    assert 0.0 <= np.median(rel) < 0.06, np.median(rel)
    assert np.percentile(np.abs(rel), 90) < 0.15


def test_box_mask_uses_pixel_centres():
    m = box_mask((1.0, 2.0, 4.0, 3.0), 6, 6)
    ys, xs = np.nonzero(m)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (1, 3, 2, 2)
