"""Model families: a folder's `config.json` `model_type` -> the family -> the module that runs it.

One module per family, each a class built from (model folder, Runtime) with the role's method:
detectors `detect`, segmenters `segment`, depth models `predict`, CLIP-like models `scores`, the
vision-language captioner `describe`. Imported lazily: torch and transformers load only when a model does.
"""

from __future__ import annotations

import importlib
from typing import Any

MODEL_TYPES: dict[str, str] = {
    "grounding-dino": "grounding-dino",
    "mm-grounding-dino": "grounding-dino",
    "owlv2": "owlv2",
    "owlvit": "owlv2",
    "sam": "sam",
    "sam2": "sam2",
    "sam2_video": "sam2",
    "depth_anything": "depth-anything",
    "depth_pro": "depth-pro",
    "zoedepth": "zoedepth",
    "clip": "clip",
    "siglip": "siglip",
    "siglip2": "siglip",
}
FAMILIES: dict[str, str] = {
    "grounding-dino": "refspatial_gen.perception.grounding_dino:GroundingDinoDetector",
    "owlv2": "refspatial_gen.perception.owlv2:Owlv2Detector",
    "sam": "refspatial_gen.perception.sam:SamSegmenter",
    "sam2": "refspatial_gen.perception.sam2:Sam2Segmenter",
    "depth-anything": "refspatial_gen.perception.depth_anything:DepthAnythingMetric",
    "depth-pro": "refspatial_gen.perception.depth_pro:DepthProMetric",
    "zoedepth": "refspatial_gen.perception.zoedepth:ZoeDepthMetric",
    "clip": "refspatial_gen.perception.clip:ClipScorer",
    "siglip": "refspatial_gen.perception.clip:ClipScorer",
    "vlm": "refspatial_gen.perception.vlm:VlmCaptioner",
}
# model types transformers maps to image-text-to-text that we accept as captioners
VLM_TYPES = (
    "blip",
    "blip-2",
    "florence2",
    "idefics3",
    "smolvlm",
    "llava",
    "paligemma",
    "qwen2_vl",
    "qwen2_5_vl",
    "git",
    "instructblip",
    "llava_onevision",
)


def family_of(config: dict[str, Any]) -> str | None:
    """The family of a model from its config.json contents (None when not one we run)."""
    mt = str(config.get("model_type", ""))
    if mt in MODEL_TYPES:
        return MODEL_TYPES[mt]
    if mt in VLM_TYPES:
        return "vlm"
    return None


def family_class(family: str) -> type:
    if family not in FAMILIES:
        raise KeyError(f"unknown model family {family!r} (known: {', '.join(sorted(FAMILIES))})")
    mod, attr = FAMILIES[family].split(":")
    return getattr(importlib.import_module(mod), attr)
