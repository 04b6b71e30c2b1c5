"""Apple Depth Pro (`apple/DepthPro-hf`) from a local folder: metric depth and the focal length.

Depth Pro predicts a canonical inverse depth and (with its field-of-view head) the horizontal field of
view. Metric depth is f_px / (inverse_depth x W), with f_px = W / 2 / tan(fov / 2) from the model, or a
focal length known from the photo (a calibration file or EXIF), which then also fixes the depth's scale.
transformers' Depth Pro image processor needs torchvision, which this project does not install, so the
preprocessing is done here from the folder's `preprocessor_config.json`: scale to [0, 1], normalise
(mean = std = 0.5 by default), then resize (bilinear, no antialiasing) to `size` (1536 x 1536), the order
the published processor uses. Every image becomes the same square input, so any images batch together.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from refspatial_gen.perception.depth import DepthPrediction
from refspatial_gen.perception.runtime import Runtime, from_folder


def _pre(path: str) -> dict:
    p = Path(path) / "preprocessor_config.json"
    d = json.loads(p.read_text(encoding="utf-8")) if p.is_file() else {}
    size = d.get("size") or {"height": 1536, "width": 1536}
    return {
        "size": (int(size["height"]), int(size["width"])),
        "mean": tuple(d.get("image_mean") or (0.5,) * 3),
        "std": tuple(d.get("image_std") or (0.5,) * 3),
        "rescale": float(d.get("rescale_factor") or 1 / 255),
    }


class DepthProMetric:
    family = "depth-pro"
    predicts_focal = True

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.pre = _pre(path)
        _, self.model = from_folder(path, rt, "AutoModelForDepthEstimation", None)

    def _inputs(self, images: list[np.ndarray]):
        import torch

        mean = torch.tensor(self.pre["mean"]).view(1, 3, 1, 1)
        std = torch.tensor(self.pre["std"]).view(1, 3, 1, 1)
        x = torch.from_numpy(np.stack(images).astype(np.float32)).permute(0, 3, 1, 2) * self.pre["rescale"]
        x = (x - mean) / std
        return torch.nn.functional.interpolate(
            x, size=self.pre["size"], mode="bilinear", align_corners=False, antialias=False
        )

    def predict(self, images: list[np.ndarray]) -> list[DepthPrediction]:
        """Per image: depth for a focal length of 1 px (metres; times f_px gives metric depth) and the
        model's own focal length in pixels (None without a field-of-view head or when it is implausible)."""
        import torch

        px = torch.cat([self._inputs([img]) for img in images]).to(self.rt.device)  # each to the same square
        with torch.no_grad():
            res = self.model(pixel_values=px)
        out = []
        for b, img in enumerate(images):
            H, W = img.shape[:2]
            inv = torch.nn.functional.interpolate(
                res.predicted_depth.float()[b : b + 1, None].cpu(), size=(H, W), mode="bilinear", align_corners=False
            )[0, 0]
            fov = getattr(res, "field_of_view", None)
            deg = None if fov is None else float(fov.reshape(-1)[b])
            f_model = None
            if deg is not None and np.isfinite(deg) and 5.0 <= deg <= 170.0:
                f_model = float(0.5 * W / np.tan(0.5 * np.deg2rad(deg)))
            unit = 1.0 / torch.clamp(inv * W, min=1e-8, max=1e8)
            out.append(DepthPrediction(unit.numpy().astype(np.float32), True, f_model))
        return out
