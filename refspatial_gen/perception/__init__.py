"""Perception from local models: unlabelled photos and box-less RGB-D scans -> objects (docs/perception.md).

A `perception:` section in an image or scan source's config turns on, in order: image filters
(filters.py), optional tagging (clip.py), open-vocabulary detection (grounding_dino.py, owlv2.py; boxes.py
keeps boxes one-to-one with objects), masks from boxes (sam.py, sam2.py), metric depth and intrinsics for
photos (depth_anything.py, depth_pro.py, zoedepth.py, depth.py), captions (captions.py, vlm.py), and for
scans the lifting and fusion of detections across key frames (fusion.py, scan.py). One module per model
family, each loaded from a local folder through transformers (registry.py, runtime.py); outputs cached on
disk (cache.py); config in config.py. Importing this package loads no model library.
"""

from refspatial_gen.perception.config import check_perception, normalise, perception_field

__all__ = ["check_perception", "normalise", "perception_field"]
