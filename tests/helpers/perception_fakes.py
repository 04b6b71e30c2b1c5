"""Test doubles for perception models: folders that pass the recipe check, runners that return given answers.

`install(monkeypatch, runners)` makes `Perceiver.model(role)` return `runners[<folder name>]`, so no
torch model is loaded; every call is recorded in the runner's `calls` list.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from refspatial_gen.perception.boxes import Detection
from refspatial_gen.perception.cache import array_hash
from refspatial_gen.perception.depth import DepthPrediction


def model_folder(root: Path, name: str, model_type: str, **extra) -> Path:
    d = Path(root) / name
    d.mkdir(parents=True, exist_ok=True)
    (d / "config.json").write_text(json.dumps({"model_type": model_type, **extra}))
    return d


class FakeDetector:
    """Returns, per image (by pixel hash), the (box, label, score) list it was given; nothing otherwise."""

    def __init__(self, answers: dict[str, list[tuple[tuple[float, float, float, float], str, float]]] | None = None):
        self.answers = answers or {}
        self.calls: list[int] = []

    def detect(self, images, prompts, labels, floor, per_chunk=0):
        self.calls.append(len(images))
        out = []
        for img in images:
            dets = [Detection(tuple(map(float, b)), float(s), lab) for b, lab, s in self.answers.get(array_hash(img), [])]
            out.append([d for d in dets if d.label in labels and d.score >= floor])
        return out


class FakeSegmenter:
    """Returns the mask given for (image hash, box) whose box best matches the asked one (IoU >= 0.95: the
    asked box went through rounding), else the box filled."""

    def __init__(self, masks: dict[tuple[str, tuple], np.ndarray] | None = None):
        self.masks = masks or {}
        self.calls: list[int] = []

    def _lookup(self, h, box):
        from refspatial_gen.perception.boxes import iou_matrix

        cands = [(k[1], m) for k, m in self.masks.items() if k[0] == h]
        if not cands:
            return None
        ious = iou_matrix(np.array([box]), np.array([c[0] for c in cands]))[0]
        k = int(np.argmax(ious))
        return cands[k][1] if ious[k] >= 0.95 else None

    def segment(self, images, boxes, multimask=True):
        self.calls.append(len(images))
        out = []
        for img, bxs in zip(images, boxes):
            h = array_hash(img)
            ms = []
            for b in bxs:
                m = self._lookup(h, b)
                if m is None:
                    m = np.zeros(img.shape[:2], bool)
                    m[int(b[1]):int(np.ceil(b[3])), int(b[0]):int(np.ceil(b[2]))] = True
                ms.append(m)
            out.append((ms, [0.9] * len(ms)))
        return out


class FakeDepth:
    """A tilted floor plane seen from a camera 1.5 m high (metric), with an optional focal prediction."""

    def __init__(self, focal: float | None = None, per_focal: bool = False):
        self.focal, self.per_focal = focal, per_focal
        self.calls: list[int] = []

    def predict(self, images):
        self.calls.append(len(images))
        out = []
        for img in images:
            H, W = img.shape[:2]
            v = np.arange(H, dtype=np.float32)[:, None] + 0.5
            d = np.where(v > H / 2, 1.5 * (W / 2) / np.maximum(v - H / 2, 1.0), 20.0).astype(np.float32)
            d = np.broadcast_to(np.minimum(d, 20.0), (H, W)).copy()
            out.append(DepthPrediction(d / (self.focal or 1.0) if self.per_focal else d, self.per_focal, self.focal))
        return out


def install(monkeypatch, runners: dict[str, object]) -> None:
    import refspatial_gen.perception.pipeline as pipeline

    def fake_load(path, rt):
        return runners[Path(path).name]

    monkeypatch.setattr(pipeline, "load_model", fake_load)
    pipeline._perceiver.cache_clear()


def register_depth_estimator(monkeypatch) -> None:
    """The `perception` depth estimator is a registry entry (depth/__init__.py); nothing to patch any more."""
    import refspatial_gen.depth as depth

    assert "perception" in depth.estimator_names()
