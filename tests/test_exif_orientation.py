"""Decoders keep the stored pixel grid: an EXIF orientation tag must not rotate an image away from the depth map,
intrinsics and annotations that refer to the stored grid (OpenCV rotates by default; PIL does not)."""

import numpy as np
from PIL import Image

from refspatial_gen.sources.image.annotations import read_panoptic_ids
from refspatial_gen.sources.image.source import decode_rgb
from refspatial_gen.sources.scan.fileio import read_rgb


def _tagged_jpeg(path, orientation: int) -> np.ndarray:
    """A 20x40 image, left quarter white, saved with an EXIF orientation tag; returns the stored pixels."""
    a = np.zeros((20, 40, 3), np.uint8)
    a[:, :10] = 255
    exif = Image.Exif()
    exif[0x0112] = orientation
    Image.fromarray(a).save(path, quality=95, exif=exif.tobytes())
    return a


def test_rgb_decoders_ignore_exif_orientation(tmp_path):
    for orientation in (3, 6, 8):  # 180 degrees, 90 clockwise, 90 counter-clockwise
        p = tmp_path / f"o{orientation}.jpg"
        stored = _tagged_jpeg(p, orientation)
        for decode in (read_rgb, decode_rgb):
            got = decode(p)
            assert got.shape == stored.shape, f"{decode.__name__} rotated orientation {orientation}"
            assert got[:, :10].mean() > 200 and got[:, 12:].mean() < 50, f"{decode.__name__} flipped orientation {orientation}"


def test_panoptic_label_map_is_never_rotated(tmp_path):
    ids = np.zeros((20, 40, 3), np.uint8)
    ids[:, :10] = (7, 0, 0)  # segment id 7 in the left quarter
    exif = Image.Exif()
    exif[0x0112] = 6
    p = tmp_path / "pan.png"
    Image.fromarray(ids).save(p, exif=exif.tobytes())
    out = read_panoptic_ids(p, 40, 20, "img")
    assert out.shape == (20, 40) and (out[:, :10] == 7).all() and (out[:, 10:] == 0).all()
