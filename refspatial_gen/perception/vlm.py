"""An optional local vision-language captioner (SmolVLM, Florence-2, BLIP, ... any image-text-to-text model).

It writes a short free-text description of each object from a crop around its box, stored as the
object's `description` with `provenance.description = "vlm:<folder>"`. Model text is never checked
against the scene, so nothing in a question or answer is built from it: it is training context only.
Decoding is greedy (no sampling), so the text is a function of the crop and the model.
"""

from __future__ import annotations

import numpy as np

from refspatial_gen.perception.runtime import Runtime, from_folder, to_device


class VlmCaptioner:
    family = "vlm"

    def __init__(self, path: str, rt: Runtime) -> None:
        self.rt = rt
        self.processor, self.model = from_folder(path, rt, "AutoModelForImageTextToText")
        self.chat = getattr(self.processor, "chat_template", None) is not None

    def _inputs(self, crop: np.ndarray, prompt: str):
        if self.chat:
            msgs = [{"role": "user", "content": [{"type": "image"}, {"type": "text", "text": prompt}]}]
            text = self.processor.apply_chat_template(msgs, add_generation_prompt=True)
            return self.processor(images=[crop], text=text, return_tensors="pt")
        return self.processor(images=crop, text=prompt, return_tensors="pt")

    def describe(self, crops: list[np.ndarray], prompts: list[str], max_new_tokens: int) -> list[str]:
        import torch

        out = []
        for crop, prompt in zip(crops, prompts):
            enc = to_device(dict(self._inputs(crop, prompt)), self.rt.device)
            with torch.no_grad():
                ids = self.model.generate(**enc, max_new_tokens=max_new_tokens, do_sample=False)
            n_in = enc["input_ids"].shape[-1] if "input_ids" in enc else 0
            new = (
                ids[:, n_in:]
                if (not self.model.config.is_encoder_decoder and ids.shape[-1] > n_in and self.chat)
                else ids
            )
            text = self.processor.batch_decode(new, skip_special_tokens=True)[0].strip()
            if text.lower().startswith(prompt.lower()):
                text = text[len(prompt) :].strip()
            out.append(" ".join(text.split()))
        return out
