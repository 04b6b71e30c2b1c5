"""`depth-anything`: Depth Anything (V2) through transformers, from a LOCAL model folder only.

The folder is what `save_pretrained` writes (config.json, weights, preprocessor_config.json). Nothing is
ever downloaded: loading uses `local_files_only=True` and a missing folder is an error. Relative models
predict disparity up to an affine map, recovered to metres by `depth.scale.recover_metric`; metric
models (`depth_estimation_type: metric` in their config) predict metres directly.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from refspatial_gen.depth import CameraPrior, DepthResult
from refspatial_gen.depth.scale import METHODS, recover_metric
from refspatial_gen.schema import Field


def _dir_exists(v: str) -> str | None:
    return None if Path(v).is_dir() else f"model folder {v!r} does not exist (models are never downloaded)"


RELATIVE_OPTIONS = {
    "output": Field(
        str,
        default="auto",
        choices=("auto", "disparity", "depth", "metric"),
        doc="what the model predicts; auto reads the model config",
    ),
    "scale_recovery": Field(str, default="contacts", choices=METHODS, doc="how relative output becomes metric"),
    "camera_height": Field(float, default=1.5, min=0.05, doc="prior for scale recovery (m)"),
    "pitch_deg": Field(float, default=0.0, min=-60.0, doc="prior downward pitch for scale recovery"),
    "median_depth": Field(float, default=None, min=0.01, doc="target median depth for scale_recovery: median"),
    "max_depth": Field(float, default=80.0, min=0.1, doc="depths beyond this count as unknown (m)"),
}


@lru_cache(maxsize=2)
def _load(model_dir: str, stamp: float):
    import torch  # noqa: F401  (fail early with a clear ImportError)
    from transformers import AutoImageProcessor, AutoModelForDepthEstimation

    proc = AutoImageProcessor.from_pretrained(model_dir, local_files_only=True)
    model = AutoModelForDepthEstimation.from_pretrained(model_dir, local_files_only=True).eval()
    return proc, model


class RelativeToMetric:
    """Shared tail of model-based estimators: prediction -> metric depth with a stated origin."""

    output: str
    scale_recovery: str
    camera_height: float
    pitch_deg: float
    median_depth: float | None
    max_depth: float

    def _finish(self, pred: np.ndarray, kind: str, prior: CameraPrior, name: str) -> DepthResult:
        import cv2

        pred = np.asarray(pred, np.float32)
        if pred.shape != (prior.height, prior.width):
            pred = cv2.resize(pred, (prior.width, prior.height), interpolation=cv2.INTER_CUBIC)
        if kind == "metric":
            d = np.where(np.isfinite(pred) & (pred > 0), pred, 0.0).astype(np.float32)
            origin, meta, metric = f"{name}:metric", {}, True
        else:
            h = prior.camera_height if prior.camera_height is not None else self.camera_height
            p = prior.pitch if prior.pitch is not None else float(np.deg2rad(self.pitch_deg))
            d, how, meta = recover_metric(
                pred, kind, prior, self.scale_recovery, h, p, self.median_depth, np.random.default_rng(0)
            )  # fixed seed: a pure function of the image
            origin, metric = f"{name}:{kind}+{how}", self.scale_recovery != "none"
        d[d > self.max_depth] = 0.0
        return DepthResult(d, metric, origin, meta)


class DepthAnythingDepth(RelativeToMetric):
    name = "depth-anything"
    OPTIONS = {
        "model_dir": Field(str, required=True, check=_dir_exists, doc="local save_pretrained folder"),
        "threads": Field(int, default=1, min=1, doc="torch CPU threads"),
        **RELATIVE_OPTIONS,
    }

    def __init__(
        self,
        model_dir: str,
        threads: int = 1,
        output: str = "auto",
        scale_recovery: str = "contacts",
        camera_height: float = 1.5,
        pitch_deg: float = 0.0,
        median_depth: float | None = None,
        max_depth: float = 80.0,
    ) -> None:
        msg = _dir_exists(model_dir)
        if msg:
            raise FileNotFoundError(msg)
        self.model_dir, self.threads, self.output = str(Path(model_dir).resolve()), threads, output
        self.scale_recovery, self.camera_height, self.pitch_deg = scale_recovery, camera_height, pitch_deg
        self.median_depth, self.max_depth = median_depth, max_depth

    def estimate(self, rgb: np.ndarray, prior: CameraPrior) -> DepthResult:
        import torch

        proc, model = _load(self.model_dir, Path(self.model_dir, "config.json").stat().st_mtime)
        kind = self.output
        if kind == "auto":
            kind = "metric" if getattr(model.config, "depth_estimation_type", "relative") == "metric" else "disparity"
        torch.set_num_threads(self.threads)
        inputs = proc(images=np.ascontiguousarray(rgb), return_tensors="pt")
        with torch.no_grad():
            pred = model(**inputs).predicted_depth
        pred = torch.nn.functional.interpolate(
            pred[:, None].float(), size=(prior.height, prior.width), mode="bicubic", align_corners=False
        )[0, 0].numpy()
        return self._finish(pred, kind, prior, "depth-anything")
