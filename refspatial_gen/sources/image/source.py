"""The `image` source: annotated photos + depth (estimated or provided) + intrinsics -> lifted 3D Frames.

Unit key: "image:<image id>" (keys.py). `load` reads the collection from `config["_input"]`, the absolute
input folder the recipe loader puts in every source's config. One unit = one photo = one Frame, built by
build.py (which lists the reasons a photo is dropped); config.py holds the recipe fields.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.model import Frame
from refspatial_gen.sources.image.annotations import load_collection
from refspatial_gen.sources.image.build import build_frame, decode_rgb
from refspatial_gen.sources.image.checks import raise_if_invalid
from refspatial_gen.sources.image.config import CONFIG_FIELDS, estimator_from_config, with_defaults
from refspatial_gen.sources.image.keys import KEY_PREFIX, input_root, parse_key, unit_key
from refspatial_gen.sources.image.surfaces import SUPPORT_CATEGORIES

_with_defaults = with_defaults  # the name tests and benches import

__all__ = [
    "CONFIG_FIELDS",
    "KEY_PREFIX",
    "SUPPORT_CATEGORIES",
    "ImageSource",
    "build_frame",
    "decode_rgb",
    "estimator_from_config",
    "input_root",
    "parse_key",
    "unit_key",
    "with_defaults",
]


class ImageSource:
    """Annotated 2D photos lifted to 3D. See docs/image.md."""

    name = "image"
    CONFIG_FIELDS = CONFIG_FIELDS

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        if not input_path:
            raise ValueError("the image source needs an input folder (recipe `input:` or --input)")
        cfg = with_defaults(config)
        if cfg["perception"]:
            from refspatial_gen.perception.photos import photo_ids

            keys = [unit_key(iid) for iid in photo_ids(input_path, cfg)]
            return keys if scenes is None else keys[:scenes]
        coll = load_collection(input_path, cfg["format"], cfg["annotations"], cfg["images_dir"])
        keys = [unit_key(iid) for iid in coll.ids()]
        return keys if scenes is None else keys[:scenes]

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        iid = parse_key(unit_key)
        root = input_root(config)
        cfg = with_defaults(config)
        if cfg["perception"]:
            from refspatial_gen.perception.photos import load_photo

            return [load_photo(root, iid, rng, cfg, build_frame)]
        coll = load_collection(root, cfg["format"], cfg["annotations"], cfg["images_dir"])
        rec = coll.images.get(iid)
        if rec is None:
            raise DropUnit("unknown_image", f"{iid} not in {root}")
        raise_if_invalid(rec.meta)  # a malformed annotation entry drops its image (sources/image/checks.py)
        return [build_frame(coll, rec, rng, cfg)]
