"""Grounding DINO (and MM-Grounding-DINO) through transformers, from a local folder.

The model reads one text of at most `max_text_len` tokens ("cup. dining table. chair."), so a vocabulary
is cut into chunks of whole names and each chunk is one forward pass. A query's score for a name is the
highest sigmoid of its token logits over that name's tokens (found from the tokenizer's character
offsets); its label is the best-scoring name of the chunk. Boxes come normalised to the image (the pixel
mask hides padding) and are scaled to pixels here. Images are batched only with images of the same size,
so padding never changes a result.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.boxes import Detection
from refspatial_gen.perception.runtime import Runtime, from_folder, to_device


class GroundingDinoDetector:
    family = "grounding-dino"

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModelForZeroShotObjectDetection")
        self.max_tokens = int(getattr(self.model.config, "max_text_len", 256))

    def _chunks(self, prompts: list[str], per_chunk: int) -> list[tuple[str, list[list[int]]]]:
        """Prompt texts of whole names, each with the token indices of every name."""
        tok = self.processor.tokenizer
        out, start = [], 0
        while start < len(prompts):
            end = min(len(prompts), start + per_chunk)
            while True:
                text = ". ".join(prompts[start:end]) + "."
                enc = tok(text, return_offsets_mapping=True, add_special_tokens=True)
                if len(enc["input_ids"]) <= self.max_tokens or end == start + 1:
                    break
                end -= 1
            spans, pos = [], 0
            for name in prompts[start:end]:
                lo = text.index(name, pos)
                hi = lo + len(name)
                pos = hi
                spans.append([i for i, (a, b) in enumerate(enc["offset_mapping"]) if b > a and a >= lo and b <= hi])
            out.append((text, spans))
            start = end
        return out

    def detect(
        self, images: list[np.ndarray], prompts: list[str], labels: list[str], floor: float, per_chunk: int = 40
    ) -> list[list[Detection]]:
        """Raw candidates (score >= floor) per image; `labels[i]` names the detections of `prompts[i]`."""
        import torch

        results: list[list[Detection]] = [[] for _ in images]
        offset = 0
        for text, spans in self._chunks(prompts, per_chunk):
            batch = self.processor(images=list(images), text=[text] * len(images), return_tensors="pt")
            with torch.no_grad():
                out = self.model(**to_device(dict(batch), self.rt.device))
            probs = torch.sigmoid(out.logits.float()).cpu().numpy()  # (B, Q, max_text_len)
            boxes = out.pred_boxes.float().cpu().numpy()  # (B, Q, 4) cx cy w h, normalised
            per_name = np.stack([probs[..., s].max(axis=-1) if s else np.zeros(probs.shape[:2]) for s in spans], -1)
            for b, img in enumerate(images):
                H, W = img.shape[:2]
                best = per_name[b].argmax(axis=-1)
                score = per_name[b][np.arange(len(best)), best]
                for q in np.nonzero(score >= floor)[0]:
                    cx, cy, w, h = boxes[b, q]
                    box = (
                        float((cx - w / 2) * W),
                        float((cy - h / 2) * H),
                        float((cx + w / 2) * W),
                        float((cy + h / 2) * H),
                    )
                    results[b].append(Detection(box, float(score[q]), labels[offset + int(best[q])]))
            offset += len(spans)
        return results
