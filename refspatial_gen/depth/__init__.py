"""Depth estimators for the image source, behind one interface, chosen by name in the recipe.

    est = get_estimator("geometric", {"camera_height": 1.5})
    result = est.estimate(rgb, prior)        # -> DepthResult(depth_m, is_metric, origin, meta)

Registered: `provided` (a depth image next to the photo), `depth-anything` (Depth Anything V2 through
transformers, loaded from a local folder only), `onnx` (any depth model as a local ONNX file) and
`geometric` (no weights: objects placed where they meet the ground, from a camera height/pitch prior).
Heavy dependencies (torch, transformers, onnxruntime) are imported only inside the estimators that use
them. Each estimator declares `OPTIONS: dict[str, schema.Field]` so recipes are checked before any work.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from refspatial_gen.core.registry import Registry


@dataclass
class CameraPrior:
    """What is known about the picture before depth: intrinsics (Camera's convention: pixel u spans
    [u, u+1), its centre is u + 0.5), the camera
    height/pitch/roll prior (metres, radians; pitch > 0 looks down), and per-image side information some
    estimators need: the provided depth file, object masks with ids (geometric placement, scale
    recovery) and a mask of pixels known to be ground (panoptic floor/road stuff)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    camera_height: float | None = None
    pitch: float | None = None
    roll: float = 0.0
    depth_path: str | None = None
    depth_scale: float | None = None  # units per metre of the provided depth file, when the dataset says so
    masks: list[tuple[int, np.ndarray]] = field(default_factory=list)
    categories: dict[int, str] = field(default_factory=dict)  # object id -> category (size priors)
    ground_mask: np.ndarray | None = None

    def rays(self) -> np.ndarray:
        """(H, W, 3) camera-frame rays with z = 1 through every pixel centre."""
        vs, us = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64) + 0.5
        return np.stack([(us - self.cx) / self.fx, (vs - self.cy) / self.fy, np.ones_like(us)], axis=-1)

    def up_cam(self) -> np.ndarray:
        """World up in camera coordinates implied by the pitch/roll prior (pitch>0: camera looks down)."""
        p = 0.0 if self.pitch is None else self.pitch
        up = np.array([0.0, -np.cos(p), -np.sin(p)])
        c, s = np.cos(self.roll), np.sin(self.roll)  # roll about the optical axis
        return np.array([c * up[0] - s * up[1], s * up[0] + c * up[1], up[2]])


@dataclass
class DepthResult:
    """z-depth in metres (float32 HxW, 0 = unknown). `is_metric=False` means known only up to scale;
    `origin` names the estimator and how scale was found; `meta` holds per-estimator details
    (e.g. the geometric estimator's per-object contact notes under "objects")."""

    depth_m: np.ndarray
    is_metric: bool
    origin: str
    meta: dict[str, Any] = field(default_factory=dict)


class DepthEstimator(Protocol):
    name: str

    def estimate(self, rgb: np.ndarray, prior: CameraPrior) -> DepthResult: ...


# name -> "module:Class"
ESTIMATORS: Registry[type] = Registry("depth estimator")
ESTIMATORS.add("provided", "refspatial_gen.depth.provided:ProvidedDepth")
ESTIMATORS.add("depth-anything", "refspatial_gen.depth.depth_anything:DepthAnythingDepth")
ESTIMATORS.add("onnx", "refspatial_gen.depth.onnx_model:OnnxDepth")
ESTIMATORS.add("geometric", "refspatial_gen.depth.geometric:GeometricDepth")
ESTIMATORS.add("perception", "refspatial_gen.perception.photos:PerceptionDepth")  # photos loaded with `perception:`


def estimator_names() -> list[str]:
    return sorted(ESTIMATORS.names())


def estimator_class(name: str) -> type:
    return ESTIMATORS.get(name)


def check_options(name: str, options: dict[str, Any]) -> str | None:
    """Validate an estimator's recipe options; returns an error message or None."""
    try:
        cls = estimator_class(name)
    except KeyError as e:
        return str(e.args[0])
    fields = getattr(cls, "OPTIONS", {})
    for k in sorted(options):
        if k not in fields:
            return f"unknown option {k!r} for depth estimator {name!r} (known: {', '.join(sorted(fields))})"
    for k, f in fields.items():
        v = options.get(k)
        if v is None:
            if f.required:
                return f"depth estimator {name!r} needs option {k!r}"
            continue
        from refspatial_gen.schema import _type_name, _type_ok

        if not _type_ok(v, f.type):
            return f"option {k!r} must be {_type_name(f.type)}, got {v!r}"
        if f.choices is not None and v not in f.choices:
            return f"option {k!r} must be one of {', '.join(map(str, f.choices))}, got {v!r}"
        if f.min is not None and v < f.min:
            return f"option {k!r} must be >= {f.min}, got {v}"
        if f.check is not None:
            msg = f.check(v)
            if msg:
                return f"option {k!r}: {msg}"
    return None


def get_estimator(name: str, options: dict[str, Any] | None = None) -> DepthEstimator:
    """Build an estimator by registered name; unknown options raise ValueError."""
    options = dict(options or {})
    msg = check_options(name, options)
    if msg:
        raise ValueError(msg)
    cls = estimator_class(name)
    full = {k: (options[k] if options.get(k) is not None else f.default) for k, f in cls.OPTIONS.items()}
    return cls(**full)


__all__ = ["CameraPrior", "DepthEstimator", "DepthResult", "check_options", "estimator_names", "get_estimator"]
