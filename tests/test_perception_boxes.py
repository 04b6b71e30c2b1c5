"""Detections -> kept boxes: thresholds, NMS per name, one name per box, one-to-one matching; deterministic."""

import numpy as np

from refspatial_gen.perception.boxes import Detection, iou_matrix, match_one_to_one, nms, one_to_one, select

KW = dict(threshold=0.3, thresholds=None, nms_iou=0.5, duplicate_iou=0.85, max_detections=30, min_box_fraction=0.0005,
          max_box_fraction=0.9)


def test_iou():
    M = iou_matrix(np.array([[0, 0, 10, 10]]), np.array([[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30]]))
    assert np.allclose(M, [[1.0, 50 / 150, 0.0]])


def test_nms_keeps_the_best_of_overlapping_boxes_of_one_name():
    dets = [Detection((0, 0, 10, 10), 0.6, "cup"), Detection((1, 0, 11, 10), 0.9, "cup"),
            Detection((50, 50, 60, 60), 0.5, "cup")]
    kept, gone = nms(dets, 0.5)
    assert [d.score for d in kept] == [0.9, 0.5] and [d.score for d in gone] == [0.6]


def test_one_box_two_names_keeps_the_better_name():
    kept, gone = one_to_one([Detection((0, 0, 10, 10), 0.7, "mug"), Detection((0, 0, 10, 10.5), 0.8, "cup"),
                             Detection((0, 0, 10, 20), 0.9, "bottle")], 0.85)
    assert [d.label for d in kept] == ["bottle", "cup"] and [d.label for d in gone] == ["mug"]


def test_select_counts_every_drop_by_reason():
    W, H = 200, 100
    dets = [Detection((0, 0, 50, 50), 0.9, "cup"), Detection((2, 0, 52, 50), 0.8, "cup"),  # nms
            Detection((0, 0, 50, 51), 0.7, "mug"),  # same object, other name
            Detection((100, 10, 150, 60), 0.35, "person"),  # below person's own threshold
            Detection((100, 10, 101, 11), 0.9, "bowl"),  # too small
            Detection((-10, -10, 300, 300), 0.9, "table"),  # the whole picture, clipped to the image
            Detection((60, 60, 90, 90), 0.2, "cup")]  # below the default threshold
    kept, drops = select(dets, W, H, **{**KW, "thresholds": {"person": 0.5}})
    assert [(d.label, d.score) for d in kept] == [("cup", 0.9)]
    assert drops == {"below_threshold": 2, "box_too_large": 1, "box_too_small": 1, "duplicate_label": 1, "nms": 1}
    assert kept[0].box == (0, 0, 50, 50)


def test_select_is_independent_of_input_order(rng):
    dets = [Detection(tuple(float(x) for x in np.sort(rng.uniform(0, 100, 4).reshape(2, 2), axis=0).T.reshape(-1)),
                      float(rng.uniform(0.3, 1.0)), str(rng.choice(["cup", "mug", "bowl"]))) for _ in range(40)]
    a, da = select([Detection(d.box, d.score, d.label) for d in dets], 100, 100, **KW)
    b, db = select([Detection(d.box, d.score, d.label) for d in dets[::-1]], 100, 100, **KW)
    assert [(d.box, d.score, d.label) for d in a] == [(d.box, d.score, d.label) for d in b] and da == db


def test_max_detections_keeps_the_best():
    dets = [Detection((i * 10.0, 0, i * 10.0 + 8, 8), 0.5 + i / 100, f"n{i}") for i in range(10)]
    kept, drops = select(dets, 100, 100, **{**KW, "max_detections": 3})
    assert [d.label for d in kept] == ["n9", "n8", "n7"] and drops == {"over_max_detections": 7}


def test_match_one_to_one_maximises_total_iou():
    a = [(0, 0, 10, 10), (8, 0, 18, 10)]
    b = [(7, 0, 17, 10), (0, 0, 11, 10), (50, 50, 60, 60)]
    assert [(i, j) for i, j, _ in match_one_to_one(a, b, 0.5)] == [(0, 1), (1, 0)]
    assert match_one_to_one([], b) == [] and match_one_to_one(a, [(100, 100, 110, 110)]) == []
