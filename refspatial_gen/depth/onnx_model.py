"""`onnx`: any single-image depth model exported to a local ONNX file, run with onnxruntime on CPU.

Input: one float32 NCHW tensor (RGB scaled to [0, 1], normalised with `mean`/`std`, resized to
`input_size` or to the model's static input shape). Output: the first output, squeezed to 2D and
resized back to the image. `output` says whether it is disparity, relative depth or metres; relative
outputs go through the same scale recovery as Depth Anything.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from refspatial_gen.depth import CameraPrior, DepthResult
from refspatial_gen.depth.depth_anything import RELATIVE_OPTIONS, RelativeToMetric
from refspatial_gen.schema import Field


def _file_exists(v: str) -> str | None:
    return None if Path(v).is_file() else f"ONNX file {v!r} does not exist (models are never downloaded)"


@lru_cache(maxsize=2)
def _session(path: str, stamp: float, threads: int):
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    so.inter_op_num_threads = 1
    return ort.InferenceSession(path, sess_options=so, providers=["CPUExecutionProvider"])


class OnnxDepth(RelativeToMetric):
    name = "onnx"
    OPTIONS = {
        "model_path": Field(str, required=True, check=_file_exists, doc="local .onnx file"),
        "input_size": Field(
            list, default=None, doc="[height, width] fed to the model (default: its static shape, else 518)"
        ),
        "mean": Field(list, default=[0.485, 0.456, 0.406]),
        "std": Field(list, default=[0.229, 0.224, 0.225]),
        "threads": Field(int, default=1, min=1),
        **{k: v for k, v in RELATIVE_OPTIONS.items() if k != "output"},
        "output": Field(str, default="disparity", choices=("disparity", "depth", "metric")),
    }

    def __init__(
        self,
        model_path: str,
        input_size: list | None = None,
        mean: list | None = None,
        std: list | None = None,
        threads: int = 1,
        output: str = "disparity",
        scale_recovery: str = "contacts",
        camera_height: float = 1.5,
        pitch_deg: float = 0.0,
        median_depth: float | None = None,
        max_depth: float = 80.0,
    ) -> None:
        msg = _file_exists(model_path)
        if msg:
            raise FileNotFoundError(msg)
        self.model_path = str(Path(model_path).resolve())
        self.input_size = None if input_size is None else (int(input_size[0]), int(input_size[1]))
        self.mean = np.asarray(mean if mean is not None else [0.485, 0.456, 0.406], np.float32)
        self.std = np.asarray(std if std is not None else [0.229, 0.224, 0.225], np.float32)
        self.threads, self.output, self.scale_recovery = threads, output, scale_recovery
        self.camera_height, self.pitch_deg, self.median_depth, self.max_depth = (
            camera_height,
            pitch_deg,
            median_depth,
            max_depth,
        )

    def estimate(self, rgb: np.ndarray, prior: CameraPrior) -> DepthResult:
        import cv2

        sess = _session(self.model_path, Path(self.model_path).stat().st_mtime, self.threads)
        inp = sess.get_inputs()[0]
        size = self.input_size
        if size is None:
            shape = inp.shape
            size = (shape[2], shape[3]) if all(isinstance(s, int) for s in shape[2:4]) else (518, 518)
        x = cv2.resize(rgb, (size[1], size[0]), interpolation=cv2.INTER_CUBIC).astype(np.float32) / 255.0
        x = ((x - self.mean) / self.std).transpose(2, 0, 1)[None].astype(np.float32)
        out = sess.run(None, {inp.name: x})[0]
        pred = np.squeeze(np.asarray(out, np.float32))
        if pred.ndim != 2:
            raise ValueError(f"ONNX depth model output has shape {out.shape}; expected one 2D map")
        return self._finish(pred, self.output, prior, "onnx")
