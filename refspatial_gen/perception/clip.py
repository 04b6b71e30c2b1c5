"""CLIP and SigLIP image-text scores, from a local folder: the image filter, the tagger and material words.

Text embeddings are computed once per prompt list and kept for the worker's life. Scores are
probabilities: for CLIP a softmax over the prompts asked together (CLIP was trained contrastively across
texts), for SigLIP the sigmoid of each pair (SigLIP was trained with a per-pair sigmoid loss; its logit
bias is applied). Text is padded to the model's full length, as SigLIP was trained (and read without a
mask). Every image is resized to the same input, so any images batch together.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.runtime import Runtime, from_folder


def _pooled(out):
    return out.pooler_output if hasattr(out, "pooler_output") else out


class ClipScorer:
    family = "clip"

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModel")
        self.sigmoid = self.model.config.model_type in ("siglip", "siglip2")
        self._text: dict[tuple[str, ...], object] = {}

    def text_embeds(self, texts: list[str]):
        import torch

        key = tuple(texts)
        if key not in self._text:
            n = int(self.model.config.text_config.max_position_embeddings)
            embs = []
            for i in range(0, len(texts), 256):
                enc = self.processor.tokenizer(
                    list(texts[i : i + 256]), padding="max_length", max_length=n, truncation=True, return_tensors="pt"
                )
                enc = {k: v.to(self.rt.device) for k, v in enc.items() if k in ("input_ids", "attention_mask")}
                if self.sigmoid:
                    enc.pop("attention_mask", None)  # SigLIP reads max-length padded text without a mask
                with torch.no_grad():
                    e = _pooled(self.model.get_text_features(**enc)).float()
                embs.append(e / e.norm(dim=-1, keepdim=True))
            if len(self._text) > 8:
                self._text.clear()
            self._text[key] = torch.cat(embs, 0)
        return self._text[key]

    def scores(self, images: list[np.ndarray], texts: list[str]) -> np.ndarray:
        """(len(images), len(texts)) probabilities (see the module docstring)."""
        import torch

        t = self.text_embeds(texts)
        px = self.processor.image_processor(images=list(images), return_tensors="pt")["pixel_values"]
        with torch.no_grad():
            v = _pooled(self.model.get_image_features(pixel_values=px.to(self.rt.device))).float()
            v = v / v.norm(dim=-1, keepdim=True)
            logits = (v @ t.T) * self.model.logit_scale.exp().float()
            if self.sigmoid:
                logits = logits + self.model.logit_bias.float()
                p = torch.sigmoid(logits)
            else:
                p = torch.softmax(logits, dim=-1)
        return p.cpu().numpy().astype(np.float64)
