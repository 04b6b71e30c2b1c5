"""Truth data (refspatial_gen/truth): category size ranges with sources, the bearing table, and the API the
sources and the graph call (size_range, check_size, can_bear)."""

import numpy as np
import pytest

from refspatial_gen.truth import sizes as T
from refspatial_gen.truth.sizes import UNRANGED, can_bear, check_size, size_range

COCO_80 = [
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat", "traffic light",
    "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog", "horse", "sheep", "cow",
    "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella", "handbag", "tie", "suitcase", "frisbee",
    "skis", "snowboard", "sports ball", "kite", "baseball bat", "baseball glove", "skateboard", "surfboard",
    "tennis racket", "bottle", "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple",
    "sandwich", "orange", "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch",
    "potted plant", "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard",
    "cell phone", "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors",
    "teddy bear", "hair drier", "toothbrush"]
# SUN RGB-D: the votenet/mmdetection3d 10 classes and the other classes of the shared frames
SUN = ["bed", "table", "sofa", "chair", "toilet", "desk", "dresser", "night_stand", "bookshelf", "bathtub",
       "lamp", "ottoman", "pillow", "garbage_bin", "monitor", "sofa_chair", "tv", "counter", "door", "sink",
       "dresser_mirror", "box", "mirror", "picture", "window", "curtain"]
SCANNET_18 = ["cabinet", "bed", "chair", "sofa", "table", "door", "window", "bookshelf", "picture", "counter",
              "desk", "curtain", "refrigerator", "showercurtrain", "toilet", "sink", "bathtub", "garbagebin"]
# no honest range: their sizes span orders of magnitude, or the annotation covers different things
UNRANGED_BY_DESIGN = {"kite", "clock", "dresser_mirror", "box", "mirror", "picture", "window", "curtain"}


@pytest.mark.parametrize("cat", sorted(set(COCO_80 + SUN + SCANNET_18)))
def test_every_category_the_sources_produce_is_ranged_or_deliberately_not(cat):
    r = size_range(cat)
    if cat in UNRANGED_BY_DESIGN:
        assert r is None and check_size(cat, (1, 1, 1)) == UNRANGED
        return
    assert r is not None, f"{cat} has no size range"
    assert r.sources and all(T.source_text(s) for s in r.sources)  # every range cites where it comes from
    lo, hi = r.extent
    assert 0 < lo < hi
    if r.height is not None:
        assert r.height[1] <= hi + 1e-9  # an upright height never exceeds the largest extent


def test_sim_catalog_objects_are_inside_their_ranges():
    """The simulated assets are drawn from assets/catalog.yaml: every category is ranged, and the boxes
    of sampled instances (and of the external meshes, when the shared data is there) are inside."""
    from refspatial_gen.assets import build_geometry, load_catalog
    from refspatial_gen.assets.catalog import shared_data_root

    cat = load_catalog()
    for name, c in sorted(cat.categories.items()):
        assert size_range(c.label) is not None, f"{name} ({c.label}) has no size range"
        if c.builder == "external" and not shared_data_root().is_dir():
            continue
        rng = np.random.default_rng(0)
        for _ in range(1 if c.builder == "external" else 3):
            g = build_geometry(c, c.sample_dims(rng) if c.builder != "external" else {}, rng)
            lo, hi = g.bounds()
            size = np.asarray(hi) - np.asarray(lo)
            assert check_size(c.label, size) is None, (name, size.round(3), size_range(c.label))


def test_check_size_reasons_and_bounds():
    assert check_size("person", (0.5, 0.4, 1.75)) is None
    assert check_size("person", (0.6, 0.6, 3.7)) == T.TOO_TALL  # the street photo's 3.7 m person
    assert check_size("person", (0.2, 0.2, 0.2)) == T.TOO_SHORT
    assert check_size("car", (1.8, 4.4, 0.3)) == T.TOO_SHORT  # a 0.3 m car
    assert check_size("car", (1.8, 12.0, 1.5)) == T.TOO_LONG
    assert check_size("cup", (0.9, 0.9, 0.1)) == T.TOO_LARGE
    # a visible extent is a lower bound: too small is not a reason then, too large still is
    assert check_size("car", (0.3, 0.3, 0.3), dims=("height", "extent"), lower_bounds=("height", "extent")) is None
    assert check_size("car", (0.3, 0.3, 2.6), dims=("height",), lower_bounds=("height",)) == T.TOO_TALL
    assert check_size("person", (0.5, 0.5, 2.2), dims=("height",), tolerance=0.1) is None
    assert check_size("unicorn", (1, 1, 1)) == UNRANGED and size_range("unicorn") is None
    with pytest.raises(ValueError):
        check_size("person", (1, 1, 1), dims=("width",))


def test_names_and_aliases_resolve():
    assert size_range("Night_Stand") == size_range("night stand") is not None
    assert size_range("garbagebin") == size_range("garbage bin")
    assert size_range("refridgerator") == size_range("refrigerator")  # ScanNet's spelling
    assert size_range("couch") == size_range("sofa")
    assert size_range("Person") == size_range("person")  # OpenImages display names
    assert T.canonical("showercurtrain") == "shower curtain"
    assert T.typical_height("person") == 1.7


def test_bearing_table():
    # never a support in a photo: people, umbrellas, cars, buses
    for sup in ("person", "umbrella", "car", "bus", "truck", "train"):
        for obj in ("cup", "person", "car", "umbrella", "bottle"):
            assert not can_bear(sup, obj), (sup, obj)
    # furniture made to hold things, and the floor
    for sup in ("dining table", "table", "desk", "counter", "bookshelf", "night_stand", "cabinet"):
        assert can_bear(sup, "cup") and can_bear(sup, "laptop") and not can_bear(sup, "car")
    for sup in ("bed", "couch", "sofa", "chair", "bench"):
        assert can_bear(sup, "person") and can_bear(sup, "cat") and can_bear(sup, "pillow")
    assert can_bear("floor", "car") and can_bear("ground", "elephant")
    assert not can_bear("dining table", "person")  # a person behind a table is not on it
    assert can_bear("horse", "person") and can_bear("motorcycle", "person") and not can_bear("cow", "person")
    # small objects bear small objects, not much larger ones
    assert can_bear("book", "cup") and can_bear("plate", "apple")
    assert can_bear("book", "book", (0.2, 0.15, 0.03), (0.24, 0.17, 0.03))
    assert not can_bear("can", "laptop", (0.07, 0.07, 0.12), (0.33, 0.23, 0.02))  # overhang rule
    assert not can_bear("book", "tv")
    # sizes decide the class of a category whose range spans classes (a table lamp on a night stand)
    assert can_bear("night stand", "lamp", (0.5, 0.5, 0.6), (0.3, 0.3, 0.6))
    assert not can_bear("night stand", "lamp", (0.5, 0.5, 0.6), (0.5, 0.5, 1.7))
    # unknown supports bear nothing unless the caller says so
    assert not can_bear("otherfurniture", "cup") and can_bear("otherfurniture", "cup", unknown=True)


def test_sim_stacks_are_bearable():
    """The simulated layout stacks tabletop objects on flat-topped ones (books, boxes, cans...): the
    bearing table must not refuse a stack the physics made."""
    from refspatial_gen.assets import load_catalog
    from refspatial_gen.assets.shapes import BUILDERS

    cat = load_catalog()
    rng = np.random.default_rng(1)
    flat = []
    for name, c in sorted(cat.categories.items()):
        if c.builder != "external" and c.scale == "tabletop":
            g = BUILDERS[c.builder](c.sample_dims(rng), rng)
            if g.flat_top:
                flat.append(c.label)
    assert len(flat) >= 8
    for label in flat:
        assert can_bear(label, "cup") and can_bear(label, "apple"), label
