"""An annotation's visible mask, materialised per image when it is lifted, after checking that the
annotation lies inside the image (else the whole image is dropped: `annotation_out_of_bounds`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.image.records import Annotation, ImageRecord

BOUNDS_TOLERANCE_PX = 1.0  # annotations may touch the border, rounding included; more is an error


def _check_bounds(
    ann: Annotation, extent: tuple[float, float, float, float], width: int, height: int, image_id: str
) -> None:
    x0, y0, x1, y1 = extent
    t = BOUNDS_TOLERANCE_PX
    if x0 < -t or y0 < -t or x1 > width + t or y1 > height + t or not np.all(np.isfinite(extent)):
        raise DropUnit(
            "annotation_out_of_bounds",
            f"image {image_id}: annotation {ann.ann_id} ({ann.category}) spans "
            f"[{x0:.1f}, {y0:.1f}, {x1:.1f}, {y1:.1f}] outside the {width}x{height} image",
        )


def resolved_bbox(ann: Annotation, rec: ImageRecord, width: int, height: int) -> tuple[float, float, float, float]:
    """The annotation's box in pixels (OpenImages stores normalised boxes), checked against the image."""
    bb = ann.bbox
    if rec.meta.get("normalised_boxes"):
        bb = (bb[0] * width, bb[1] * height, bb[2] * width, bb[3] * height)
    _check_bounds(ann, bb, width, height, rec.image_id)
    return bb


def read_panoptic_ids(path: Path, width: int, height: int, image_id: str) -> np.ndarray:
    from refspatial_gen.core.serialize import decode_image

    try:
        blob = Path(path).read_bytes()
        if not blob:
            raise ValueError("empty file")
        img = decode_image(blob)  # a label map: never turned by an EXIF tag
    except (OSError, ValueError) as e:
        raise DropUnit("annotation_unreadable", f"image {image_id}: panoptic PNG {path} could not be decoded") from e
    if img.shape[:2] != (height, width):
        raise DropUnit(
            "annotation_size_mismatch",
            f"image {image_id}: panoptic PNG is {img.shape[1]}x{img.shape[0]}, image {width}x{height}",
        )
    rgb = img.astype(np.int64)
    return rgb[..., 0] + 256 * rgb[..., 1] + 256 * 256 * rgb[..., 2]


def annotation_mask(
    ann: Annotation, rec: ImageRecord, width: int, height: int, panoptic_ids: np.ndarray | None = None
) -> tuple[np.ndarray, bool]:
    """The annotation's visible mask (bool HxW) and whether it is a true segmentation (False: box only).

    Raises DropUnit for an annotation outside the image or of the wrong size (the whole image is dropped:
    a misregistered annotation file would make every answer about that image wrong)."""
    import cv2

    from refspatial_gen.sources.image.rle import box_mask, polygons_extent, polygons_to_mask, rle_from_coco

    bb = resolved_bbox(ann, rec, width, height)
    if ann.kind == "polygon":
        _check_bounds(ann, polygons_extent(ann.data), width, height, rec.image_id)
        return polygons_to_mask(ann.data, height, width), True
    if ann.kind == "rle":
        try:
            return rle_from_coco(ann.data, height, width).decode(), True
        except (ValueError, KeyError, TypeError) as e:
            raise DropUnit("annotation_size_mismatch", f"image {rec.image_id}: annotation {ann.ann_id}: {e}") from e
    if ann.kind == "panoptic":
        if panoptic_ids is None:
            raise DropUnit("annotation_missing", f"image {rec.image_id}: no panoptic PNG")
        return panoptic_ids == int(ann.data), True
    if ann.kind == "mask_png":
        m = cv2.imread(str(ann.data), cv2.IMREAD_GRAYSCALE)
        if m is None:
            raise DropUnit("annotation_unreadable", f"image {rec.image_id}: mask {ann.data} could not be decoded")
        if m.shape != (height, width):  # OpenImages masks come at their own resolution: resample to the image
            m = cv2.resize(m, (width, height), interpolation=cv2.INTER_NEAREST)
        return m > 127, True
    return box_mask(bb, height, width), False
