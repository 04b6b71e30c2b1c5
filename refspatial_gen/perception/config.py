"""The recipe's `perception:` section (inside an image or scan source's `config:`), checked before any work.

Every model is named by a folder: an absolute path, or a name under the models folder (`models:` in the
section, else `$REFSPATIAL_MODELS`, else `./models`, relative to where the run starts, like every other
model folder in the project). A folder that does not exist, or holds no `config.json`, is a recipe error:
nothing is ever downloaded. The model family (Grounding DINO, OWLv2, SAM, SAM 2, Depth Anything, Depth
Pro, ZoeDepth, CLIP, SigLIP, a vision-language model) is read from the folder's `config.json`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.schema import Field, check_section

INTRINSICS_ORDER = ("provided", "exif", "model", "prior")

FILTER_FIELDS: dict[str, Field] = {
    "min_side": Field(int, default=200, min=1, doc="drop images whose shorter side is smaller (pixels)"),
    "max_aspect": Field(float, default=4.0, min=1.0, doc="drop panoramas and strips beyond this aspect ratio"),
    "blur_threshold": Field(
        float, default=20.0, min=0.0, doc="variance of the Laplacian of the grey image at 512 px on the long side"
    ),
    "min_brightness": Field(float, default=25.0, min=0.0, max=255.0, doc="mean grey level below: too dark"),
    "max_brightness": Field(float, default=235.0, min=0.0, max=255.0, doc="mean grey level above: washed out"),
    "max_clipped": Field(float, default=0.4, min=0.0, max=1.0, doc="largest share of pixels at 0 or 255"),
    "duplicate_distance": Field(
        int,
        default=3,
        min=-1,
        max=64,
        doc="64-bit difference hash: an image this close to an earlier one is a duplicate (-1 turns the check off)",
    ),
    "clip": Field(dict, default=None, doc="{model, positive: [...], negative: [...], min_margin}"),
}
CLIP_FILTER_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True),
    "positive": Field(list, required=True, doc="prompts describing images to keep"),
    "negative": Field(list, required=True, doc="prompts describing images to drop"),
    "min_margin": Field(float, default=0.0, doc="best positive minus best negative probability must exceed this"),
}
DETECTOR_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True, doc="Grounding DINO or OWLv2 folder"),
    "vocabulary": Field(
        (str, list),
        default="coco",
        doc="coco | lvis | lvis-frequent | openimages | a list of names | a .txt file (one a line)",
    ),
    "exclude": Field(list, default=None, doc="names never prompted"),
    "prompt_template": Field(str, default="{}", doc="text around each name, e.g. 'a photo of a {}' for OWLv2"),
    "threshold": Field(float, default=0.3, min=0.0, max=1.0, doc="default per-category score threshold"),
    "thresholds": Field(dict, default=None, doc="per-category score thresholds {name: value}"),
    "nms_iou": Field(float, default=0.5, min=0.0, max=1.0, doc="non-maximum suppression within a category"),
    "duplicate_iou": Field(
        float,
        default=0.85,
        min=0.0,
        max=1.0,
        doc="one box, several names: keep the best name (boxes stay one-to-one with objects)",
    ),
    "max_detections": Field(int, default=30, min=1),
    "min_box_fraction": Field(float, default=0.0005, min=0.0, max=1.0, doc="smallest box area / image area"),
    "max_box_fraction": Field(float, default=0.9, min=0.0, max=1.0, doc="larger boxes are the scene, not an object"),
    "chunk": Field(int, default=40, min=1, doc="names per model call (Grounding DINO reads at most 256 tokens)"),
}
TAGGER_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True, doc="CLIP or SigLIP folder"),
    "top_k": Field(int, default=20, min=1, doc="names kept per image before detection"),
    "prompt_template": Field(str, default="a photo of a {}"),
}
SEGMENTER_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True, doc="SAM or SAM 2 folder"),
    "multimask": Field(bool, default=True, doc="three candidate masks per box, the best by predicted IoU kept"),
    "min_box_fill": Field(float, default=0.05, min=0.0, max=1.0, doc="a mask filling less of its box is dropped"),
}
DEPTH_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True, doc="a metric Depth Anything (V2), Depth Pro or ZoeDepth folder"),
    "max_depth": Field(float, default=80.0, min=0.1, doc="farther is unknown (m)"),
}
MATERIAL_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True, doc="CLIP or SigLIP folder"),
    "words": Field(list, default=["wooden", "metal", "plastic", "glass", "ceramic", "fabric", "paper", "leather"]),
    "min_margin": Field(float, default=0.15, min=0.0, max=1.0, doc="best minus second probability"),
}
VLM_FIELDS: dict[str, Field] = {
    "model": Field(str, required=True, doc="an image-text-to-text folder (SmolVLM, Florence-2, BLIP, ...)"),
    "prompt": Field(str, default="Describe the {category} in a few words."),
    "max_new_tokens": Field(int, default=16, min=1, max=256),
}
CAPTION_FIELDS: dict[str, Field] = {
    "colour": Field(bool, default=True, doc="colour words from the object's pixels (graph.colour)"),
    "material": Field(dict, default=None, doc="{model, words, min_margin}: CLIP/SigLIP zero-shot material words"),
    "vlm": Field(dict, default=None, doc="{model, prompt, max_new_tokens}: a free-text description per object"),
}
FUSION_FIELDS: dict[str, Field] = {
    "voxel": Field(float, default=0.02, min=0.002, doc="metres: point cloud grid of a fused object"),
    "match_overlap": Field(
        float, default=0.25, min=0.0, max=1.0, doc="share of a detection's points near an object's points to join it"
    ),
    "min_views": Field(int, default=1, min=1, doc="an object must be detected in this many key frames"),
    "min_points": Field(int, default=80, min=3),
    "max_frames": Field(int, default=30, min=1, doc="key frames of a sequence used for fusion"),
}
PERCEPTION_FIELDS: dict[str, Field] = {
    "models": Field(str, default=None, doc="folder holding the model folders (default $REFSPATIAL_MODELS or ./models)"),
    "device": Field(str, default="auto", choices=("auto", "cpu", "cuda")),
    "threads": Field(int, default=1, min=1, doc="torch CPU threads per worker"),
    "batch_size": Field(int, default=4, min=1, doc="images per model call (fixed blocks of the sorted image list)"),
    "cache": Field(bool, default=True, doc="keep model outputs on disk, keyed by image, model and settings"),
    "cache_dir": Field(
        str, default=None, doc="default $REFSPATIAL_CACHE/perception or ~/.cache/refspatial-gen/perception"
    ),
    "images_dir": Field(str, default=None, doc="image folder inside the input (default: images/ when present)"),
    "filters": Field(dict, default=None, doc="cheap image filters and an optional CLIP/SigLIP filter"),
    "tagger": Field(dict, default=None, doc="CLIP/SigLIP: narrow the vocabulary to each image's top names"),
    "detector": Field(dict, required=True, doc="open-vocabulary detector"),
    "segmenter": Field(dict, default=None, doc="SAM / SAM 2 masks from boxes (without: box annotations)"),
    "depth": Field(dict, default=None, doc="metric depth model (photos; scans use their measured depth)"),
    "intrinsics": Field(list, default=list(INTRINSICS_ORDER), doc="order of intrinsics sources"),
    "captions": Field(dict, default=None),
    "fusion": Field(dict, default=None, doc="box-less scans: multi-view fusion settings"),
}
SUBSECTIONS: dict[str, dict[str, Field]] = {
    "filters": FILTER_FIELDS,
    "tagger": TAGGER_FIELDS,
    "detector": DETECTOR_FIELDS,
    "segmenter": SEGMENTER_FIELDS,
    "depth": DEPTH_FIELDS,
    "captions": CAPTION_FIELDS,
    "fusion": FUSION_FIELDS,
}
ROLE_FAMILIES: dict[str, tuple[str, ...]] = {
    "detector": ("grounding-dino", "owlv2"),
    "segmenter": ("sam", "sam2"),
    "depth": ("depth-anything", "depth-pro", "zoedepth"),
    "tagger": ("clip", "siglip"),
    "filters.clip": ("clip", "siglip"),
    "captions.material": ("clip", "siglip"),
    "captions.vlm": ("vlm",),
}


def models_root(section: dict[str, Any] | None) -> Path:
    """Where model names resolve: the section's `models`, else $REFSPATIAL_MODELS, else ./models."""
    v = (section or {}).get("models") or os.environ.get("REFSPATIAL_MODELS") or "models"
    return Path(v).expanduser()


def resolve_model(name: str, section: dict[str, Any] | None) -> Path:
    """A model folder: absolute or relative paths with a separator as given, bare names under the models root."""
    p = Path(name).expanduser()
    if p.is_absolute() or len(p.parts) > 1:
        return p.resolve()
    return (models_root(section) / p).resolve()


def model_problem(name: str, section: dict[str, Any] | None, families: tuple[str, ...]) -> str | None:
    """Why a model folder cannot be used (missing, no config.json, wrong family), or None."""
    from refspatial_gen.perception.registry import family_of

    p = resolve_model(name, section)
    if not p.is_dir():
        return (
            f"model folder {str(p)!r} does not exist (models are never downloaded; docs/perception.md "
            f"says which checkpoint to place there)"
        )
    cfg = p / "config.json"
    if not cfg.is_file():
        return f"model folder {str(p)!r} has no config.json (not a save_pretrained folder)"
    try:
        conf = json.loads(cfg.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        return f"{cfg}: {e}"
    fam = family_of(conf)
    if fam not in families:
        return f"model folder {str(p)!r} holds a {fam or 'unknown'} model; expected {' or '.join(families)}"
    if fam == "depth-anything" and conf.get("depth_estimation_type") != "metric":
        return (
            f"model folder {str(p)!r} holds a relative Depth Anything model; perception needs a metric one "
            f"(relative models: the image source's `depth: {{estimator: depth-anything}}`)"
        )
    return None


def _section(data: Any, fields: dict[str, Field], where: str) -> tuple[dict[str, Any], str | None]:
    errors: list[RecipeError] = []
    out = check_section(data, fields, "", {}, ("perception", *where.split(".")) if where else ("perception",), errors)
    return out, (errors[0].message if errors else None)


def normalise(value: dict[str, Any] | None) -> dict[str, Any] | None:
    """The section with every default filled in (sub-sections too); None stays None. Raises ValueError."""
    if not value:
        return None
    top, msg = _section(value, PERCEPTION_FIELDS, "")
    if msg:
        raise ValueError(msg)
    for key, fields in SUBSECTIONS.items():
        if top.get(key) is None and key not in ("filters", "captions", "fusion"):
            continue
        sub, msg = _section(top.get(key) or {}, fields, key)
        if msg:
            raise ValueError(msg)
        top[key] = sub
    f = top["filters"]
    if f.get("clip") is not None:
        f["clip"], msg = _section(f["clip"], CLIP_FILTER_FIELDS, "filters.clip")
        if msg:
            raise ValueError(msg)
    c = top["captions"]
    for key, fields in (("material", MATERIAL_FIELDS), ("vlm", VLM_FIELDS)):
        if c.get(key) is not None:
            c[key], msg = _section(c[key], fields, f"captions.{key}")
            if msg:
                raise ValueError(msg)
    for name, v in ((top.get("detector") or {}).get("thresholds") or {}).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
            raise ValueError(f"detector.thresholds.{name}: must be a score between 0 and 1, got {v!r}")
    bad = [x for x in top["intrinsics"] if x not in INTRINSICS_ORDER]
    if bad or not top["intrinsics"]:
        raise ValueError(f"intrinsics must list some of {', '.join(INTRINSICS_ORDER)}, got {top['intrinsics']!r}")
    return top


def model_entries(cfg: dict[str, Any]) -> list[tuple[str, str]]:
    """(role, model name) for every model the normalised section uses."""
    out = []
    for role in ("detector", "segmenter", "depth", "tagger"):
        if cfg.get(role):
            out.append((role, cfg[role]["model"]))
    if cfg["filters"].get("clip"):
        out.append(("filters.clip", cfg["filters"]["clip"]["model"]))
    for key in ("material", "vlm"):
        if cfg["captions"].get(key):
            out.append((f"captions.{key}", cfg["captions"][key]["model"]))
    return out


def check_perception(value: Any) -> str | None:
    """Recipe check for the `perception:` field: the first problem as a message (the loader adds file:line)."""
    if value is None:
        return None
    if not isinstance(value, dict):
        return "must be a mapping (see docs/perception.md)"
    try:
        cfg = normalise(value)
    except ValueError as e:
        return str(e)
    from refspatial_gen.perception.vocab import vocabulary_problem

    msg = vocabulary_problem(cfg["detector"]["vocabulary"])
    if msg:
        return f"detector.vocabulary: {msg}"
    for role, name in model_entries(cfg):
        msg = model_problem(name, cfg, ROLE_FAMILIES[role])
        if msg:
            return f"{role}.model: {msg}"
    return None


def perception_field() -> Field:
    """The Field a source adds to its CONFIG_FIELDS."""
    return Field(
        dict,
        default=None,
        check=check_perception,
        doc="open-vocabulary perception from local models (docs/perception.md)",
    )
