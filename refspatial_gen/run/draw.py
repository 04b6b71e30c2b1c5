"""Overlay drawing for preview images: points, 2D boxes, projected 3D boxes, free-space polygons, text.

Why a module of its own: the preview must show exactly what a QA pair claims (answer points at the
pixels a trainer would read, boxes where the geometry puts them), so projection and scaling live in one
place and are tested on their own. Drawing uses Pillow (anti-aliased shapes, a real TrueType font with
degree signs and arrows) with the DejaVu fonts that matplotlib ships, so output does not depend on the
fonts of the machine. Everything is deterministic: same inputs, same pixels.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D

RGB = tuple[int, int, int]

# Colours chosen to stay readable on the box world and on real photos.
ANSWER = (255, 40, 220)  # magenta: rare in scenes, unlike red
TARGET_2D = (255, 210, 0)
TARGET_3D = (0, 220, 255)
FREE_SPACE = (40, 200, 90)
ANSWER_REGION = (255, 120, 0)
KEY_STEP = (255, 150, 40)
OPTION = (200, 80, 255)
WHITE = (255, 255, 255)
BLACK = (0, 0, 0)

# The 12 edges of a Box3D: corners are indexed by sign bits (x, y, z) in Box3D.corners() order.
BOX_EDGES: tuple[tuple[int, int], ...] = tuple(
    (i, j) for i in range(8) for j in range(i + 1, 8) if bin(i ^ j).count("1") == 1
)


@lru_cache(maxsize=16)
def font(size: int, style: str = "regular") -> ImageFont.FreeTypeFont:
    """DejaVu from matplotlib's data folder (same glyphs on every machine); Pillow's default as fallback."""
    names = {"regular": "DejaVuSans.ttf", "bold": "DejaVuSans-Bold.ttf", "mono": "DejaVuSansMono.ttf"}
    try:
        import matplotlib

        path = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / names[style]
        return ImageFont.truetype(str(path), size)
    except (ImportError, OSError):
        return ImageFont.load_default(size)


def project_points(camera: Camera, points_world: np.ndarray) -> np.ndarray:
    """World points -> pixel (u, v); rows behind the camera are NaN."""
    uv, _ = camera.project(np.asarray(points_world, float).reshape(-1, 3))
    return uv


def project_polygon(camera: Camera, polygon_xy: Sequence[Sequence[float]], z: float) -> np.ndarray | None:
    """A horizontal world polygon at height z -> its pixel outline, or None if any vertex is behind the camera."""
    pts = np.array([[float(x), float(y), float(z)] for x, y in polygon_xy], float)
    if len(pts) < 3:
        return None
    uv = project_points(camera, pts)
    if not np.all(np.isfinite(uv)):
        return None
    return uv


def plane_visibility(camera: Camera, depth: np.ndarray, z: float, tol: float = 0.01) -> np.ndarray:
    """Which pixels see the horizontal world plane at height z (not hidden by something nearer).

    Each pixel's ray meets the plane at camera depth t; the plane is seen there when the measured
    depth is unknown (0) or not nearer than t by more than `tol` metres plus 1%. Rays that never meet
    the plane in front of the camera are False.
    """
    H, W = depth.shape
    vs, us = np.mgrid[0:H, 0:W]
    d_cam = np.stack([(us + 0.5 - camera.cx) / camera.fx, (vs + 0.5 - camera.cy) / camera.fy, np.ones((H, W))], -1)
    R, o = camera.world_from_cam[:3, :3], camera.world_from_cam[:3, 3]
    dz = d_cam @ R[2]  # world z component of each ray (camera z of the ray is 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - o[2]) / dz
    hits = np.isfinite(t) & (t > 1e-6)
    seen = (depth <= 0) | (depth >= t - (tol + 0.01 * t))
    return hits & seen


def project_box_edges(camera: Camera, box: Box3D) -> list[tuple[np.ndarray, np.ndarray]]:
    """The box's 12 edges as pixel segments; edges with an end behind the camera are left out."""
    uv = project_points(camera, box.corners())
    return [(uv[i], uv[j]) for i, j in BOX_EDGES if np.all(np.isfinite(uv[i])) and np.all(np.isfinite(uv[j]))]


@dataclass
class Overlay:
    """An RGB image scaled by `scale` for display, with drawing in original-image pixel coordinates."""

    image: Image.Image
    scale: float

    @classmethod
    def from_rgb(
        cls, rgb: np.ndarray, display_width: int = 720, min_scale: float = 0.25, max_scale: float = 3.0
    ) -> Overlay:
        h, w = rgb.shape[:2]
        scale = float(min(max_scale, max(min_scale, display_width / w)))
        size = (max(1, int(round(w * scale))), max(1, int(round(h * scale))))
        img = Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8), "RGB")
        resample = Image.Resampling.BILINEAR if scale >= 1 else Image.Resampling.BOX
        return cls(img.resize(size, resample).convert("RGBA"), scale)

    def _xy(self, u: float, v: float) -> tuple[float, float]:
        return float(u) * self.scale, float(v) * self.scale

    def _layer(self) -> tuple[Image.Image, ImageDraw.ImageDraw]:
        layer = Image.new("RGBA", self.image.size, (0, 0, 0, 0))
        return layer, ImageDraw.Draw(layer)

    def _merge(self, layer: Image.Image) -> None:
        self.image = Image.alpha_composite(self.image, layer)

    def polygon(
        self,
        uv: np.ndarray,
        color: RGB,
        fill_alpha: int = 70,
        width: int = 2,
        visible: np.ndarray | None = None,
        hidden_alpha: float = 0.25,
    ) -> None:
        """A translucent filled polygon with an opaque outline (pixel coordinates of the source image).

        `visible` (bool, source-image size) marks where the polygon's surface is seen; elsewhere (behind
        an object) the drawing fades to `hidden_alpha` of its opacity, so free space never seems to lie
        on top of the objects standing in front of it.
        """
        pts = [self._xy(u, v) for u, v in np.asarray(uv, float)]
        layer, d = self._layer()
        d.polygon(pts, fill=(*color, fill_alpha))
        d.line(pts + [pts[0]], fill=(*color, 255), width=width, joint="curve")
        if visible is not None:
            vis = Image.fromarray(np.asarray(visible, bool).astype(np.uint8) * 255, "L")
            vis = np.asarray(vis.resize(self.image.size, Image.Resampling.NEAREST)) > 0
            arr = np.array(layer)
            arr[..., 3] = np.where(vis, arr[..., 3], (arr[..., 3] * hidden_alpha).astype(np.uint8))
            layer = Image.fromarray(arr, "RGBA")
        self._merge(layer)

    def rect(
        self, bbox: Sequence[float], color: RGB, width: int = 2, label: str | None = None, label_below: bool = False
    ) -> None:
        """A 2D box (x0, y0, x1, y1) in pixels, exclusive max, as the data model stores it; its label sits
        above the top-left corner, or under the bottom-left one (so two boxes on one object stay readable)."""
        x0, y0 = self._xy(bbox[0], bbox[1])
        x1, y1 = self._xy(bbox[2], bbox[3])
        layer, d = self._layer()
        d.rectangle([x0, y0, x1 - 1, y1 - 1], outline=(*color, 255), width=width)
        if label:
            self._label(d, x0, y1 if label_below else y0, label, color, above=not label_below)
        self._merge(layer)

    def segments(self, segs: Iterable[tuple[np.ndarray, np.ndarray]], color: RGB, width: int = 2) -> None:
        layer, d = self._layer()
        for a, b in segs:
            d.line([self._xy(*a), self._xy(*b)], fill=(*color, 255), width=width)
        self._merge(layer)

    def point(
        self, u: float, v: float, color: RGB, label: str | None = None, radius: int = 6, hollow: bool = False
    ) -> None:
        """A marker centred on pixel (u, v) of the source image (pass pixel centres, i.e. +0.5)."""
        x, y = self._xy(u, v)
        layer, d = self._layer()
        r = radius
        if hollow:
            d.ellipse([x - r, y - r, x + r, y + r], outline=(*BLACK, 255), width=4)
            d.ellipse([x - r, y - r, x + r, y + r], outline=(*color, 255), width=2)
        else:
            d.ellipse([x - r - 3, y - r - 3, x + r + 3, y + r + 3], fill=(*BLACK, 255))
            d.ellipse([x - r - 2, y - r - 2, x + r + 2, y + r + 2], fill=(*WHITE, 255))
            d.ellipse([x - r, y - r, x + r, y + r], fill=(*color, 255))
            d.line([x - r - 5, y, x - r - 1, y], fill=(*WHITE, 255), width=2)
            d.line([x + r + 1, y, x + r + 5, y], fill=(*WHITE, 255), width=2)
        if label:
            self._label(d, x + r + 3, y - r - 3, label, color, above=False)
        self._merge(layer)

    def _label(self, d: ImageDraw.ImageDraw, x: float, y: float, text: str, color: RGB, above: bool) -> None:
        f = font(13, "bold")
        x0, t, r, b = d.textbbox((0, 0), text, font=f)
        w, h = r - x0 + 6, b - t + 4
        x = min(max(0.0, x), self.image.size[0] - w)
        y = y - h if above else y
        y = min(max(0.0, y), self.image.size[1] - h)
        d.rectangle([x, y, x + w, y + h], fill=(*BLACK, 190))
        d.text((x + 3 - x0, y + 2 - t), text, font=f, fill=(*color, 255))

    def rgb(self) -> np.ndarray:
        return np.asarray(self.image.convert("RGB"), dtype=np.uint8).copy()


def wrap(text: str, f: ImageFont.FreeTypeFont, width: int) -> list[str]:
    """Greedy word wrap by rendered width; keeps explicit newlines; breaks over-long words."""
    out: list[str] = []
    for para in text.split("\n"):
        line = ""
        for word in para.split(" "):
            cand = word if not line else f"{line} {word}"
            if f.getlength(cand) <= width:
                line = cand
                continue
            if line:
                out.append(line)
            while f.getlength(word) > width and len(word) > 1:
                k = len(word)
                while k > 1 and f.getlength(word[:k]) > width:
                    k -= 1
                out.append(word[:k])
                word = word[k:]
            line = word
        out.append(line)
    return out


def text_panel(blocks: Sequence[tuple[str, str, RGB]], width: int, size: int = 15, pad: int = 12) -> np.ndarray:
    """Blocks of (text, style, colour) wrapped to `width` pixels on a dark background -> RGB array."""
    lines: list[tuple[str, ImageFont.FreeTypeFont, RGB, int]] = []
    for text, style, color in blocks:
        f = font(size - 1 if style == "mono" else size, style)
        step = int(round(size * 1.35))
        for ln in wrap(text, f, width - 2 * pad):
            lines.append((ln, f, color, step))
        lines.append(("", f, color, step // 2))  # gap between blocks
    height = pad * 2 + sum(s for *_, s in lines)
    img = Image.new("RGB", (width, max(height, 2 * pad)), (24, 26, 30))
    d = ImageDraw.Draw(img)
    y = pad
    for ln, f, color, step in lines:
        if ln:
            d.text((pad, y), ln, font=f, fill=color)
        y += step
    return np.asarray(img, dtype=np.uint8).copy()


def legend(items: Sequence[tuple[RGB, str]], width: int, size: int = 14, pad: int = 12) -> np.ndarray:
    """One wrapped row of colour swatches with labels -> RGB array (explains the overlay colours)."""
    f = font(size)
    row_h = size + 10
    x, y, placed = pad, pad // 2, []
    for color, label in items:
        w = 18 + int(f.getlength(label)) + 18
        if x + w > width - pad and x > pad:
            x, y = pad, y + row_h
        placed.append((x, y, color, label))
        x += w
    img = Image.new("RGB", (width, y + row_h + pad // 2), (24, 26, 30))
    d = ImageDraw.Draw(img)
    for x, y, color, label in placed:
        d.rectangle([x, y + 3, x + 12, y + 3 + 12], fill=color, outline=WHITE)
        d.text((x + 18, y), label, font=f, fill=(220, 220, 220))
    return np.asarray(img, dtype=np.uint8).copy()


def hstack(images: Sequence[np.ndarray], gap: int = 6, bg: RGB = (24, 26, 30)) -> np.ndarray:
    """Side-by-side images, top-aligned, padded to the tallest."""
    h = max(im.shape[0] for im in images)
    w = sum(im.shape[1] for im in images) + gap * (len(images) - 1)
    out = np.empty((h, w, 3), np.uint8)
    out[:] = bg
    x = 0
    for im in images:
        out[: im.shape[0], x : x + im.shape[1]] = im
        x += im.shape[1] + gap
    return out


def vstack(top: np.ndarray, bottom: np.ndarray, bg: RGB = (24, 26, 30)) -> np.ndarray:
    """`bottom` under `top`, both left-aligned, padded to the wider one."""
    w = max(top.shape[1], bottom.shape[1])
    out = np.empty((top.shape[0] + bottom.shape[0], w, 3), np.uint8)
    out[:] = bg
    out[: top.shape[0], : top.shape[1]] = top
    out[top.shape[0] :, : bottom.shape[1]] = bottom
    return out


def caption_above(image: np.ndarray, text: str, size: int = 16) -> np.ndarray:
    """`image` with a one-line caption strip on top (e.g. "image 1: ..." so a reader sees which image a
    question's "first image" is)."""
    strip = text_panel([(text, "bold", (255, 230, 120))], image.shape[1], size=size, pad=6)
    return vstack(strip, image)
