"""SAM 2 masks from boxes, through transformers' Sam2Model, from a local folder.

transformers' SAM 2 image processor needs torchvision, which this project does not install (its CPU
build is not on PyPI), so the preprocessing is done here from the folder's `preprocessor_config.json`:
the image is resized (PIL bilinear) to `size` (1024 x 1024 for the published checkpoints, aspect ratio
not kept), scaled to [0, 1] and normalised with `image_mean` / `image_std`; boxes are scaled by the same
factors per axis. The decoder's low-resolution mask logits are resized (bilinear) to the image and
thresholded at 0, as SAM 2's post-processing does. The best of the multimask candidates by predicted IoU
is kept. Every image is resized to the same square, so any images batch together.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from refspatial_gen.perception.runtime import Runtime, from_folder
from refspatial_gen.perception.sam import BOXES_PER_CALL, best_masks

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def preprocessing(path: str | Path) -> dict:
    """size (h, w), mean, std, rescale from preprocessor_config.json (SAM 2 defaults where absent)."""
    p = Path(path) / "preprocessor_config.json"
    d = json.loads(p.read_text(encoding="utf-8")) if p.is_file() else {}
    size = d.get("size") or {"height": 1024, "width": 1024}
    return {
        "size": (int(size.get("height", 1024)), int(size.get("width", 1024))),
        "mean": tuple(d.get("image_mean") or IMAGENET_MEAN),
        "std": tuple(d.get("image_std") or IMAGENET_STD),
        "rescale": float(d.get("rescale_factor") or 1 / 255),
    }


def pixel_values(images: list[np.ndarray], pre: dict) -> np.ndarray:
    """(B, 3, h, w) float32 model input."""
    from PIL import Image

    h, w = pre["size"]
    mean, std = np.array(pre["mean"], np.float32), np.array(pre["std"], np.float32)
    out = []
    for img in images:
        r = np.asarray(Image.fromarray(img).resize((w, h), Image.BILINEAR), np.float32) * pre["rescale"]
        out.append(((r - mean) / std).transpose(2, 0, 1))
    return np.stack(out).astype(np.float32)


class Sam2Segmenter:
    family = "sam2"

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.pre = preprocessing(path)
        _, self.model = from_folder(path, rt, "AutoModel", None)

    def segment(
        self, images: list[np.ndarray], boxes: list[list[tuple[float, float, float, float]]], multimask: bool = True
    ) -> list[tuple[list[np.ndarray], list[float]]]:
        """Per image: one bool HxW mask and its predicted IoU per box."""
        import torch

        px = torch.from_numpy(pixel_values(list(images), self.pre)).to(self.rt.device)
        with torch.no_grad():
            emb = self.model.get_image_embeddings(pixel_values=px)
        sh, sw = self.pre["size"]
        out = []
        for b, img in enumerate(images):
            H, W = img.shape[:2]
            masks: list[np.ndarray] = []
            scores: list[float] = []
            for i in range(0, len(boxes[b]), BOXES_PER_CALL):
                bx = torch.tensor(
                    [
                        [
                            [x0 * sw / W, y0 * sh / H, x1 * sw / W, y1 * sh / H]
                            for x0, y0, x1, y1 in boxes[b][i : i + BOXES_PER_CALL]
                        ]
                    ],
                    dtype=torch.float32,
                )
                with torch.no_grad():
                    res = self.model(
                        image_embeddings=[e[b : b + 1] for e in emb],
                        input_boxes=bx.to(self.rt.device),
                        multimask_output=multimask,
                    )
                m, s = best_masks(res.pred_masks[0].float(), res.iou_scores[0].float())
                full = torch.nn.functional.interpolate(m.cpu(), size=(H, W), mode="bilinear", align_corners=False)
                masks += [np.asarray(x[0] > 0.0) for x in full.numpy()]
                scores += [float(v) for v in s.cpu().numpy()]
            out.append((masks, scores))
        return out
