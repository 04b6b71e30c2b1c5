"""OWLv2 (and OWL-ViT, whose images are resized without padding) through transformers, from a local folder.

OWL scores every image patch against every text query with a dot product, so the text encoder runs once
per vocabulary (cached for the worker's life) and each image costs one vision pass however many names
are asked. A patch's label is its best-scoring name, its score the sigmoid of that logit. The image is
padded to a square (bottom and right) before resizing, so the normalised boxes are relative to the
square's side, max(H, W). Any batch works: every image is processed to the same square on its own.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.boxes import Detection
from refspatial_gen.perception.runtime import Runtime, from_folder


class Owlv2Detector:
    family = "owlv2"

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModelForZeroShotObjectDetection")
        self._text: dict[tuple[str, ...], object] = {}
        self.base = getattr(self.model, "owlv2", None) or self.model.owlvit
        self.square = self.model.config.model_type == "owlv2"  # OWL-ViT resizes without padding

    def _text_embeds(self, prompts: list[str]):
        import torch

        key = tuple(prompts)
        if key not in self._text:
            tok = self.processor.tokenizer
            n = int(self.model.config.text_config.max_position_embeddings)
            embs = []
            for i in range(0, len(prompts), 256):
                enc = tok(
                    prompts[i : i + 256], padding="max_length", max_length=n, truncation=True, return_tensors="pt"
                )
                with torch.no_grad():
                    out = self.base.get_text_features(
                        input_ids=enc["input_ids"].to(self.rt.device),
                        attention_mask=enc["attention_mask"].to(self.rt.device),
                    )
                embs.append(out.pooler_output if hasattr(out, "pooler_output") else out)
            self._text = {key: torch.cat(embs, 0)}  # one vocabulary per worker at a time
        return self._text[key]

    def detect(
        self, images: list[np.ndarray], prompts: list[str], labels: list[str], floor: float, per_chunk: int = 0
    ) -> list[list[Detection]]:
        """Raw candidates (score >= floor) per image; `labels[i]` names the detections of `prompts[i]`."""
        import torch

        query = self._text_embeds(prompts)
        px = self.processor.image_processor(images=list(images), return_tensors="pt")["pixel_values"].to(self.rt.device)
        with torch.no_grad():
            fmap, _ = self.model.image_embedder(pixel_values=px)
            B, h, w, d = fmap.shape
            feats = fmap.reshape(B, h * w, d)
            logits, _ = self.model.class_predictor(feats, query[None].expand(B, -1, -1), None)
            boxes = self.model.box_predictor(feats, fmap)
        probs = torch.sigmoid(logits.float()).cpu().numpy()  # (B, patches, names)
        boxes = boxes.float().cpu().numpy()
        results: list[list[Detection]] = []
        for b, img in enumerate(images):
            H, W = img.shape[:2]
            sx, sy = (float(max(H, W)),) * 2 if self.square else (float(W), float(H))
            best = probs[b].argmax(axis=-1)
            score = probs[b][np.arange(len(best)), best]
            dets = []
            for p in np.nonzero(score >= floor)[0]:
                cx, cy, bw, bh = boxes[b, p]
                box = (
                    float((cx - bw / 2) * sx),
                    float((cy - bh / 2) * sy),
                    float((cx + bw / 2) * sx),
                    float((cy + bh / 2) * sy),
                )
                dets.append(Detection(box, float(score[p]), labels[int(best[p])]))
            results.append(dets)
        return results
