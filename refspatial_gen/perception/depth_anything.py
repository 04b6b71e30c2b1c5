"""Depth Anything V2, metric variants (the `...-Metric-Indoor/Outdoor-...-hf` checkpoints), from a local folder.

A metric checkpoint (`depth_estimation_type: metric` in its config) predicts metres directly (its head
is scaled by `max_depth`: 20 m indoor, 80 m outdoor). Relative checkpoints are refused by the recipe check:
they need scale recovery, which the `depth-anything` depth estimator of the image source does. The
prediction is resized (bicubic) to the image. It predicts no focal length. Images are batched only with
images of the same size (the processor keeps the aspect ratio, so sizes decide the input shape).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.depth import DepthPrediction
from refspatial_gen.perception.runtime import Runtime, from_folder, to_device


class DepthAnythingMetric:
    family = "depth-anything"
    predicts_focal = False

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModelForDepthEstimation", "AutoImageProcessor")
        if getattr(self.model.config, "depth_estimation_type", "relative") != "metric":
            raise ValueError(f"{path}: a relative Depth Anything model; perception needs a metric checkpoint")

    def predict(self, images: list[np.ndarray]) -> list[DepthPrediction]:
        """Metric depth (float32 HxW, metres) per image; no focal prediction."""
        import torch

        enc = self.processor(images=list(images), return_tensors="pt")
        with torch.no_grad():
            pred = self.model(**to_device(dict(enc), self.rt.device)).predicted_depth.float()
        out = []
        for b, img in enumerate(images):
            H, W = img.shape[:2]
            d = torch.nn.functional.interpolate(pred[b : b + 1, None], size=(H, W), mode="bicubic", align_corners=False)
            out.append(DepthPrediction(d[0, 0].cpu().numpy().astype(np.float32), False, None))
        return out
