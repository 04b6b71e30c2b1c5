"""`provided` depth: a depth image stored next to each photo (RGB-D datasets, phone depth maps).

Encodings: `mm` (uint16, 1000 per metre: Kinect, SUN RGB-D, ScanNet), `tum` (uint16, 5000 per metre),
`float` (float32 metres: .tiff/.exr/.npy), `scale` (integers with an explicit `scale` per metre) and
`auto` (uint16 -> the dataset's own scale if the reader knows it, else mm; float -> metres).
A file that is missing, undecodable or of another size than the image drops the image with a reason.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.depth import CameraPrior, DepthResult
from refspatial_gen.schema import Field

SCALES = {"mm": 1000.0, "tum": 5000.0}


def read_depth_file(path: str | Path) -> np.ndarray:
    """Raw depth array as stored (uint16 / float); raises DropUnit when it cannot be read."""
    import cv2

    p = Path(path)
    if not p.is_file():
        raise DropUnit("depth_missing", f"no depth file {p}")
    if p.suffix == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except (ValueError, OSError) as e:
            raise DropUnit("depth_unreadable", f"{p}: {e}") from e
    else:
        arr = cv2.imread(str(p), cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
        if arr is None:
            raise DropUnit("depth_unreadable", f"{p} could not be decoded")
    if arr.ndim == 3:
        arr = arr[..., 0]
    if arr.ndim != 2:
        raise DropUnit("depth_unreadable", f"{p}: depth array has shape {arr.shape}")
    return arr


def decode_depth(
    raw: np.ndarray, encoding: str, scale: float | None = None, dataset_scale: float | None = None
) -> np.ndarray:
    """Raw array -> float32 metres, 0 for missing/invalid values."""
    if encoding == "float" or (encoding == "auto" and raw.dtype.kind == "f"):
        d = raw.astype(np.float32)
    elif raw.dtype.kind not in "ui":
        raise DropUnit("depth_unreadable", f"depth of dtype {raw.dtype} does not match encoding {encoding!r}")
    elif raw.dtype == np.uint8:
        raise DropUnit("depth_unreadable", "8-bit depth images carry no metric depth")
    else:
        if encoding == "scale":
            per_m = scale
        elif encoding == "auto":
            per_m = dataset_scale or SCALES["mm"]
        else:
            per_m = SCALES[encoding]
        d = raw.astype(np.float32) / np.float32(per_m)
    d = np.where(np.isfinite(d) & (d > 0), d, 0.0).astype(np.float32)
    return d


class ProvidedDepth:
    name = "provided"
    OPTIONS = {
        "encoding": Field(
            str,
            default="auto",
            choices=("auto", "mm", "tum", "float", "scale"),
            doc="how the stored values map to metres",
        ),
        "scale": Field(float, default=None, min=1e-9, doc="stored units per metre (encoding: scale)"),
        "pattern": Field(
            str,
            default="{stem}_depth.png",
            doc="depth file next to the image; {stem} = image name without extension, "
            "{dir} = image folder (e.g. '{dir}/../depth/{stem}.png')",
        ),
        "max_depth": Field(float, default=20.0, min=0.1, doc="values beyond this (metres) count as missing"),
    }

    def __init__(
        self,
        encoding: str = "auto",
        scale: float | None = None,
        pattern: str = "{stem}_depth.png",
        max_depth: float = 20.0,
    ) -> None:
        if encoding == "scale" and not scale:
            raise ValueError("encoding 'scale' needs the option 'scale' (units per metre)")
        self.encoding, self.scale, self.pattern, self.max_depth = encoding, scale, pattern, max_depth

    def resolve_path(self, image_path: str | Path) -> Path:
        """Where this image's depth file is expected under `pattern`."""
        p = Path(image_path)
        rel = self.pattern.format(stem=p.stem, name=p.name, dir=str(p.parent))
        q = Path(rel)
        return q if q.is_absolute() else p.parent / q

    def estimate(self, rgb: np.ndarray, prior: CameraPrior) -> DepthResult:
        if prior.depth_path is None:
            raise DropUnit("depth_missing", "the provided-depth estimator got no depth file")
        raw = read_depth_file(prior.depth_path)
        if raw.shape != (prior.height, prior.width):
            raise DropUnit(
                "depth_size_mismatch",
                f"{prior.depth_path}: depth is {raw.shape[1]}x{raw.shape[0]}, image {prior.width}x{prior.height}",
            )
        d = decode_depth(raw, self.encoding, self.scale, prior.depth_scale)
        d[d > self.max_depth] = 0.0
        return DepthResult(d, True, f"provided:{self.encoding}", {"file": Path(prior.depth_path).name})
