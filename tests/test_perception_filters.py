"""Image filters: each cheap check drops with its reason, near-duplicates keep the first copy, CLIP margin."""

import numpy as np
import pytest

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.perception import filters as F
from refspatial_gen.perception.config import FILTER_FIELDS

DEFAULTS = {k: f.default for k, f in FILTER_FIELDS.items()}


def _photo(rng, h=300, w=400):
    """A textured image (noise blurred a little: sharp, mid-grey)."""
    import cv2

    img = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
    return cv2.GaussianBlur(img, (3, 3), 0)


@pytest.mark.parametrize("make,reason", [
    (lambda p: p[:150, :150], "image_too_small"),
    (lambda p: np.concatenate([p] * 5, axis=1), "image_aspect"),
    (lambda p: (p // 20).astype(np.uint8), "image_too_dark"),
    (lambda p: np.clip(p.astype(int) + 200, 0, 255).astype(np.uint8), "image_washed_out"),
    (lambda p: np.repeat(np.where(p.mean(-1, keepdims=True) > 127, 255, 0), 3, -1).astype(np.uint8), "image_clipped"),
    (lambda p: np.full_like(p, 128), "image_blurry"),
])
def test_each_cheap_filter_has_its_reason(rng, make, reason):
    p = _photo(rng)
    assert F.cheap_checks(p, DEFAULTS)["blur"] > DEFAULTS["blur_threshold"]
    with pytest.raises(DropUnit) as e:
        F.cheap_checks(make(p), DEFAULTS)
    assert e.value.reason == reason


def test_real_photos_pass_the_defaults(shared_data):
    from refspatial_gen.sources.image.source import decode_rgb

    files = sorted((shared_data / "coco_tiny_train2017" / "images").glob("*.jpg"))[:10]
    reasons = []
    for f in files:
        try:
            F.cheap_checks(decode_rgb(f), DEFAULTS)
        except DropUnit as e:
            reasons.append(e.reason)
    assert len(reasons) <= 1, reasons


def test_blur_score_does_not_depend_on_resolution(rng):
    import cv2

    g = F.grey(_photo(rng, 600, 800))
    big = cv2.resize(g, (1600, 1200), interpolation=cv2.INTER_CUBIC)
    assert abs(F.blur_score(big) - F.blur_score(g)) / F.blur_score(g) < 0.5


def test_duplicates_keep_the_first_copy(rng, tmp_path):
    from PIL import Image

    a, b = _photo(rng, 240, 320), _photo(rng, 240, 320)
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(b).save(tmp_path / "b.png")
    Image.fromarray(a).save(tmp_path / "c.jpg", quality=70)  # the same photo re-encoded
    Image.fromarray(a[:, ::-1]).save(tmp_path / "d.png")  # mirrored: another picture
    listing = tuple((p.stem, str(p), p.stat().st_size, 0) for p in sorted(tmp_path.iterdir()))
    assert F.duplicate_index(listing, 3, str(tmp_path / "cache")) == {"c": "a"}
    assert F.duplicate_index(listing, 3, str(tmp_path / "cache")) == {"c": "a"}  # read back from disk
    assert list((tmp_path / "cache" / "duplicates").iterdir())


def test_multi_index_hashing_equals_brute_force(rng):
    base = [int(x) for x in rng.integers(0, 2**63, 60)]
    hashes = []
    for i, h in enumerate(base):
        hashes.append((f"{i:03d}a", h))
        flips = rng.choice(64, int(rng.integers(0, 6)), replace=False)
        hashes.append((f"{i:03d}b", h ^ int(sum(1 << int(f) for f in flips))))
    hashes.sort()
    for d in (0, 2, 3, 5):
        got = F.duplicates(hashes, d)
        want, firsts = {}, []
        for iid, h in hashes:
            near = [j for j, hj in firsts if bin(h ^ hj).count("1") <= d]
            if near:
                want[iid] = min(near)
            else:
                firsts.append((iid, h))
        assert got == want


class _Scorer:
    def __init__(self, p):
        self.p = np.array([p])

    def scores(self, images, texts):
        assert len(texts) == self.p.shape[1]
        return self.p


def test_clip_filter_margin():
    cfg = {"positive": ["a room", "a table"], "negative": ["a screenshot"], "min_margin": 0.1}
    assert F.clip_check(_Scorer([0.5, 0.3, 0.2]), None, cfg) == {"clip_margin": 0.3}
    with pytest.raises(DropUnit) as e:
        F.clip_check(_Scorer([0.3, 0.2, 0.5]), None, cfg)
    assert e.value.reason == "image_rejected_by_clip" and "a screenshot" in e.value.detail
