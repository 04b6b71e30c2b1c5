"""Scan readers: each parses one on-disk format into ScanViews. Chosen by name or detected from the folder.

A reader is a class with `name`, `detect(root) -> bool`, `views(root, config) -> list[str]` (sorted,
deterministic view ids, "sequence/frame" for multi-frame scans) and `read(root, view_id, config) -> ScanView`.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any, Protocol

from refspatial_gen.sources.scan.view import ScanView


class ScanReader(Protocol):
    name: str

    def detect(self, root: Path) -> bool: ...

    def views(self, root: Path, config: dict[str, Any]) -> list[str]: ...

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView: ...


# name -> "module:Class"; detection tries them in this order (most specific first)
READERS: dict[str, str] = {
    "generic": "refspatial_gen.sources.scan.readers.generic:GenericReader",
    "sunrgbd": "refspatial_gen.sources.scan.readers.sunrgbd:SunRGBDReader",
    "scannet": "refspatial_gen.sources.scan.readers.scannet:ScanNetReader",
    "colmap": "refspatial_gen.sources.scan.readers.colmap:ColmapReader",
    "mcap": "refspatial_gen.sources.scan.readers.mcap_reader:McapReader",
    "usd": "refspatial_gen.sources.scan.readers.usd:UsdReader",
    "rgbd_trajectory": "refspatial_gen.sources.scan.readers.trajectory:TrajectoryReader",
}


def get_reader(name: str) -> ScanReader:
    if name not in READERS:
        raise KeyError(f"unknown scan reader {name!r} (known: {', '.join(READERS)})")
    mod, attr = READERS[name].split(":")
    return getattr(importlib.import_module(mod), attr)()


def detect_reader(root: Path) -> str:
    """The first reader (in READERS order) that recognises the folder or file."""
    for name in READERS:
        if get_reader(name).detect(root):
            return name
    raise ValueError(f"no scan reader recognises {root} (known formats: {', '.join(READERS)})")
