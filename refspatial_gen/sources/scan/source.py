"""ScanSource: real scans (and scan-like recordings) -> Frames, one keyframe per unit.

Unit keys are `scan:<reader>:<folder relative to the input root, '.' for the root>#<view id>`: no
absolute path, so moving or copying the data folder changes neither the keys nor (the unit's random
generator derives from the key) the output bytes. `load` resolves the folder against `config["_input"]`,
the absolute input folder the recipe loader puts in every source's config. Views are listed sorted by
the reader, then thinned to every `keyframe_stride`-th view of each sequence; blur and the minimum
number of visible objects are checked when the frame is loaded (DropUnit "blurry" /
"too_few_visible_objects").
"""

from __future__ import annotations

from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.model import Frame
from refspatial_gen.perception.config import perception_field
from refspatial_gen.schema import Field
from refspatial_gen.sources.scan.fileio import DEPTH_ENCODINGS
from refspatial_gen.sources.scan.frames import view_to_frame
from refspatial_gen.sources.scan.readers import READERS, detect_reader, get_reader

CONFIG_FIELDS: dict[str, Field] = {
    "reader": Field(str, default="auto", choices=("auto", *READERS), doc="scan format; auto = detect from the folder"),
    "input": Field(str, default=None, doc="input folder when the recipe/CLI gives none"),
    "keyframe_stride": Field(int, default=1, min=1, doc="keep every n-th view of each sequence"),
    "max_views": Field(int, default=0, min=0, doc="at most this many views per input (0 = all)"),
    "blur_threshold": Field(float, default=30.0, min=0.0, doc="drop views whose variance of Laplacian is lower"),
    "min_visible_objects": Field(int, default=1, min=0, doc="drop views with fewer visible objects"),
    "min_visible_fraction": Field(float, default=0.0, min=0.0, max=1.0, doc="objects less visible are left out"),
    "min_mask_pixels": Field(int, default=64, min=1, doc="objects with fewer visible pixels are left out"),
    "occlusion_tolerance": Field(
        float, default=0.025, min=0.0, doc="metres: a pixel is occluded when depth is nearer by more"
    ),
    "mask_pad": Field(float, default=0.01, min=0.0, doc="metres of box padding when testing depth points"),
    "floor_margin": Field(float, default=0.03, min=0.0, doc="metres above a box bottom not counted as the object"),
    "max_width": Field(int, default=640, min=0, doc="downscale wider images to this width (0 = keep)"),
    "splat_scale": Field(float, default=1.0, min=0.1, doc="splat half-size in point spacings (point-cloud depth)"),
    "instance_labels": Field(
        bool,
        default=True,
        doc="use per-point instance labels when the scan has them: a "
        "box's mask keeps only pixels showing its own instance",
    ),
    "max_point_recess": Field(
        float,
        default=0.30,
        min=0.0,
        doc="box-only masks: metres an answer point may lie behind the box's entry face (else withheld: a TV in "
        "a cabinet's niche)",
    ),
    "withhold_unexplained_floor": Field(
        bool,
        default=True,
        doc="point clouds: unknown depth on the floor under unannotated things standing on it (no free space there)",
    ),
    "unexplained_min_points": Field(int, default=20, min=3, doc="low unexplained points that make such a footprint"),
    "unlabelled_stand_ins": Field(
        bool,
        default=True,
        doc="what the depth shows and no box explains becomes faint stand-ins (unlabelled.py)",
    ),
    "unlabelled_min_area": Field(
        float, default=0.004, min=0.0, max=1.0, doc="share of the image an unlabelled blob covers"
    ),
    "unlabelled_min_extent": Field(float, default=0.15, min=0.0, doc="metres across an unlabelled blob reaches"),
    "unlabelled_box_pad": Field(float, default=0.05, min=0.0, doc="metres round a box whose points it explains"),
    "unlabelled_plane_extent": Field(
        float, default=1.0, min=0.1, doc="metres: wider and taller planes are walls/ceilings"
    ),
    "unlabelled_link": Field(float, default=0.06, min=0.005, doc="metres: closer points form one blob"),
    "depth_encoding": Field(str, default="auto", choices=("auto", *DEPTH_ENCODINGS)),
    "intrinsics": Field(
        dict, default=None, doc="{width,height,fx,fy,cx,cy} (OpenCV pixel centres) for trajectories without them"
    ),
    "boxes_file": Field(str, default=None, doc="side file of boxes (generic schema) for readers without boxes"),
    "options": Field(dict, default=None, doc="reader-specific options (colmap, usd, mcap: see docs/scan.md)"),
    "perception": perception_field(),  # box-less trajectories: objects from local models (docs/perception.md)
}


def unit_key(reader: str, folder: str, view_id: str) -> str:
    """`scan:<reader>:<folder>#<view>`; `folder` is relative to the input root ('.' for the root)."""
    return f"scan:{reader}:{folder}#{view_id}"


def parse_unit_key(key: str) -> tuple[str, str, str]:
    """`scan:<reader>:<folder>#<view>` -> (reader, folder relative to the input root, view).

    Absolute folders (the old key format) and '..' are refused: a key must not depend on, or escape,
    where the input folder lives.
    """
    if not key.startswith("scan:") or "#" not in key or ":" not in key[5:]:
        raise ValueError(f"not a scan unit key: {key!r}")
    body, view = key[5:].rsplit("#", 1)
    reader, folder = body.split(":", 1)
    rel = PurePosixPath(folder)
    if not folder or rel.is_absolute() or ".." in rel.parts or Path(folder).is_absolute():
        raise ValueError(
            f"scan unit key {key!r}: the folder must be relative to the input root "
            f"(keys with absolute folders come from an older version; plan again)"
        )
    return reader, folder, view


def input_root(config: dict[str, Any]) -> Path:
    """The absolute input folder that relative unit keys resolve against (recipe/CLI `_input`, else `input`)."""
    base = config.get("_input") or config.get("input")
    if not base:
        raise ValueError(
            "scan load() needs config['_input'] (the input folder; the recipe loader sets it "
            "from --input or the recipe's `input:`)"
        )
    return Path(base).resolve()


def thin(views: list[str], stride: int) -> list[str]:
    """Every `stride`-th view of each sequence ("seq/frame"), keeping the order."""
    if stride <= 1:
        return list(views)
    out, count = [], {}
    for v in views:
        seq = v.rsplit("/", 1)[0] if "/" in v else ""
        if count.get(seq, 0) % stride == 0:
            out.append(v)
        count[seq] = count.get(seq, 0) + 1
    return out


class ScanSource:
    name = "scan"
    CONFIG_FIELDS = CONFIG_FIELDS

    def unit_keys(self, config: dict[str, Any], scenes: int | None, input_path: str | None) -> list[str]:
        path = input_path or config.get("input")
        if not path:
            raise ValueError("the scan source needs an input folder (recipe `input:` or --input PATH)")
        root = Path(path).resolve()
        if not root.exists():
            raise ValueError(f"scan input {root} does not exist")
        name = config.get("reader") or "auto"
        if name == "auto":
            name = detect_reader(root)
        views = thin(get_reader(name).views(root, config), int(config.get("keyframe_stride") or 1))
        if config.get("max_views"):
            views = views[: int(config["max_views"])]
        keys = [unit_key(name, ".", v) for v in views]
        return keys if scenes is None else keys[:scenes]

    def load(self, unit_key: str, rng: np.random.Generator, config: dict[str, Any]) -> list[Frame]:
        name, folder, view_id = parse_unit_key(unit_key)
        root = input_root(config)
        if folder != ".":
            root = root / folder
        if not root.exists():
            raise DropUnit("input_missing", f"{root} does not exist")
        view = get_reader(name).read(root, view_id, config)
        frame = view_to_frame(view, config)
        return [frame]


def load_frame(
    path: str | Path, view_id: str | None = None, config: dict[str, Any] | None = None, reader: str = "auto"
) -> Frame:
    """Convenience for tests and notebooks: one Frame from a scan folder (first view when none given)."""
    config = {k: f.default for k, f in CONFIG_FIELDS.items()} | dict(config or {})
    root = Path(path).resolve()
    name = detect_reader(root) if reader == "auto" else reader
    r = get_reader(name)
    vid = view_id if view_id is not None else r.views(root, config)[0]
    return view_to_frame(r.read(root, vid, config), config)


__all__ = ["ScanSource", "CONFIG_FIELDS", "DropUnit", "input_root", "load_frame", "parse_unit_key", "unit_key"]
