"""SAM (Segment Anything) masks from boxes, through transformers, from a local folder.

The image encoder runs once per image (batched: SAM resizes the long side to 1024 and pads to a square,
so any images batch together); the prompt encoder and mask decoder then run on the image's boxes, a few
at a time to bound memory. With `multimask`, the decoder proposes three masks per box and the one with
the highest predicted IoU is kept (SAM's own recommendation for ambiguous prompts such as boxes).
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.runtime import Runtime, from_folder

BOXES_PER_CALL = 8


def best_masks(pred_masks, iou_scores):
    """(N, K, h, w) logits and (N, K) scores -> the best candidate per box: (N, 1, h, w), (N,) scores."""
    import torch

    k = iou_scores.argmax(dim=-1)
    idx = torch.arange(len(k))
    return pred_masks[idx, k][:, None], iou_scores[idx, k]


class SamSegmenter:
    family = "sam"

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModel")

    def segment(
        self, images: list[np.ndarray], boxes: list[list[tuple[float, float, float, float]]], multimask: bool = True
    ) -> list[tuple[list[np.ndarray], list[float]]]:
        """Per image: one bool HxW mask and its predicted IoU per box."""
        import torch

        enc = self.processor(images=list(images), return_tensors="pt")
        with torch.no_grad():
            emb = self.model.get_image_embeddings(enc["pixel_values"].to(self.rt.device))
        out = []
        for b, img in enumerate(images):
            H, W = img.shape[:2]
            rh, rw = (int(x) for x in enc["reshaped_input_sizes"][b])
            masks: list[np.ndarray] = []
            scores: list[float] = []
            for i in range(0, len(boxes[b]), BOXES_PER_CALL):
                bx = torch.tensor(
                    [
                        [
                            [x0 * rw / W, y0 * rh / H, x1 * rw / W, y1 * rh / H]
                            for x0, y0, x1, y1 in boxes[b][i : i + BOXES_PER_CALL]
                        ]
                    ],
                    dtype=torch.float32,
                )
                with torch.no_grad():
                    res = self.model(
                        image_embeddings=emb[b : b + 1], input_boxes=bx.to(self.rt.device), multimask_output=multimask
                    )
                m, s = best_masks(res.pred_masks[0].float(), res.iou_scores[0].float())
                full = self.processor.image_processor.post_process_masks(
                    m[None].cpu(), enc["original_sizes"][b : b + 1], enc["reshaped_input_sizes"][b : b + 1]
                )[0]
                masks += [np.asarray(x[0], bool) for x in full.numpy()]
                scores += [float(v) for v in s.cpu().numpy()]
            out.append((masks, scores))
        return out
