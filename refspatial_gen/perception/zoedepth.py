"""ZoeDepth (`Intel/zoedepth-nyu-kitti`, `-nyu`, `-kitti`) metric depth, from a local folder.

ZoeDepth's processor pads the image by int(sqrt(side / 2) x 3) pixels on each side (reflection) to
avoid border artefacts; the prediction is resized (bicubic) to the padded size and the padding cut away,
as the published post-processing does (done here with torch, since transformers' version of that step
needs torchvision). It predicts metres and no focal length. Images are batched only with images of the
same size (the processor keeps the aspect ratio).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.depth import DepthPrediction
from refspatial_gen.perception.runtime import Runtime, from_folder, to_device


class ZoeDepthMetric:
    family = "zoedepth"
    predicts_focal = False

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModelForDepthEstimation", "AutoImageProcessor")
        self.padded = bool(getattr(self.processor, "do_pad", True))

    def predict(self, images: list[np.ndarray]) -> list[DepthPrediction]:
        import torch

        enc = self.processor(images=list(images), return_tensors="pt")
        with torch.no_grad():
            pred = self.model(**to_device(dict(enc), self.rt.device)).predicted_depth.float().cpu()
        out = []
        for b, img in enumerate(images):
            H, W = img.shape[:2]
            ph, pw = (int(np.sqrt(H / 2) * 3), int(np.sqrt(W / 2) * 3)) if self.padded else (0, 0)
            d = torch.nn.functional.interpolate(
                pred[b : b + 1, None], size=(H + 2 * ph, W + 2 * pw), mode="bicubic", align_corners=False
            )[0, 0]
            d = d[ph : ph + H, pw : pw + W]
            out.append(DepthPrediction(d.numpy().astype(np.float32), False, None))
        return out
