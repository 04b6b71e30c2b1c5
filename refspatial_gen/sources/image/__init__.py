"""Image source: annotated 2D photos (COCO, COCO panoptic, OpenImages, SUN RGB-D 2D boxes) lifted to 3D.

`ImageSource` is registered as "image" in `refspatial_gen.sources`. Importing this package is cheap;
open3d and the depth models load only when a frame is built.
"""

from refspatial_gen.sources.image.source import (
    CONFIG_FIELDS,
    ImageSource,
    build_frame,
    input_root,
    parse_key,
    unit_key,
)

__all__ = ["CONFIG_FIELDS", "ImageSource", "build_frame", "input_root", "parse_key", "unit_key"]
