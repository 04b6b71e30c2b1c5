"""Intrinsics for photos: provided by the dataset, from EXIF focal length, or a field-of-view prior.

Pixel convention (the same as core.camera.Camera): pixel (u, v) spans [u, u+1) x [v, v+1), its centre
is (u + 0.5, v + 0.5), so an image centre is (W / 2, H / 2). Every result says where it came from
(`origin`), and the image source records it in `Frame.meta["intrinsics"]`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from refspatial_gen.core.errors import DropUnit

MODES = ("auto", "provided", "exif", "fov")
EXIF_IFD = 0x8769
TAG_FOCAL_LENGTH = 0x920A
TAG_FOCAL_35MM = 0xA405
TAG_FP_XRES = 0xA20E
TAG_FP_UNIT = 0xA210
DIAG_35MM = float(np.hypot(36.0, 24.0))  # 43.27 mm: the 35 mm-equivalent focal length is defined on the diagonal
UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}


@dataclass(frozen=True)
class Intrinsics:
    fx: float
    fy: float
    cx: float
    cy: float
    origin: str  # "provided" | "exif_35mm" | "exif_focal_plane" | "fov_prior"
    detail: str = ""

    def meta(self) -> dict:
        return {
            "origin": self.origin,
            "detail": self.detail,
            "fx": round(self.fx, 4),
            "fy": round(self.fy, 4),
            "cx": round(self.cx, 4),
            "cy": round(self.cy, 4),
        }


def from_fov(width: int, height: int, hfov_deg: float) -> Intrinsics:
    f = (width / 2.0) / np.tan(np.deg2rad(hfov_deg) / 2.0)
    return Intrinsics(float(f), float(f), width / 2.0, height / 2.0, "fov_prior", f"hfov={hfov_deg:g}deg")


def from_exif(path: Path, width: int, height: int) -> Intrinsics | None:
    """Focal length in pixels from EXIF (35 mm equivalent, or focal length + focal-plane resolution)."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            exif = im.getexif()
            ifd = exif.get_ifd(EXIF_IFD) if exif else {}
    except OSError:
        return None
    cx, cy = width / 2.0, height / 2.0
    f35 = ifd.get(TAG_FOCAL_35MM)
    if f35:
        f = float(f35) * float(np.hypot(width, height)) / DIAG_35MM
        return Intrinsics(f, f, cx, cy, "exif_35mm", f"f35={float(f35):g}mm")
    fl, xres, unit = ifd.get(TAG_FOCAL_LENGTH), ifd.get(TAG_FP_XRES), ifd.get(TAG_FP_UNIT, 2)
    if fl and xres and int(unit) in UNIT_MM and float(xres) > 0:
        px_per_mm = float(xres) / UNIT_MM[int(unit)]
        f = float(fl) * px_per_mm
        return Intrinsics(f, f, cx, cy, "exif_focal_plane", f"f={float(fl):g}mm")
    return None


def from_sidecar(path: Path) -> Intrinsics | None:
    """`<stem>.intrinsics.json` next to the image: {"fx", "fy", "cx", "cy"} or {"K": 3x3}, in the
    pixel-edge convention above (cx = W / 2 for a centred principal point)."""
    side = path.with_name(path.stem + ".intrinsics.json")
    if not side.is_file():
        return None
    d = json.loads(side.read_text(encoding="utf-8"))
    if "K" in d:
        K = np.asarray(d["K"], float)
        return Intrinsics(K[0, 0], K[1, 1], K[0, 2], K[1, 2], "provided", side.name)
    return Intrinsics(float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]), "provided", side.name)


def resolve_intrinsics(
    mode: str,
    image_path: Path,
    width: int,
    height: int,
    hfov_deg: float,
    provided: tuple[float, float, float, float] | None,
) -> Intrinsics:
    """Intrinsics by `mode`: provided/exif are strict (DropUnit when absent); auto falls back in that order
    to the field-of-view prior."""
    if mode in ("auto", "provided"):
        if provided is not None:
            return Intrinsics(*map(float, provided), "provided", "annotation")
        side = from_sidecar(image_path)
        if side is not None:
            return side
        if mode == "provided":
            raise DropUnit("intrinsics_missing", f"{image_path.name}: no provided intrinsics")
    if mode in ("auto", "exif"):
        ex = from_exif(image_path, width, height)
        if ex is not None:
            return ex
        if mode == "exif":
            raise DropUnit("intrinsics_missing", f"{image_path.name}: no EXIF focal length")
    return from_fov(width, height, hfov_deg)
