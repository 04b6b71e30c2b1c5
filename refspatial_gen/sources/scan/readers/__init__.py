"""Scan readers: each parses one on-disk format into ScanViews. Chosen by name or detected from the folder.

A reader is a class with `name`, `detect(root) -> bool`, `views(root, config) -> list[str]` (sorted,
deterministic view ids, "sequence/frame" for multi-frame scans) and `read(root, view_id, config) -> ScanView`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from refspatial_gen.core.registry import Registry
from refspatial_gen.sources.scan.view import ScanView


class ScanReader(Protocol):
    name: str

    def detect(self, root: Path) -> bool: ...

    def views(self, root: Path, config: dict[str, Any]) -> list[str]: ...

    def read(self, root: Path, view_id: str, config: dict[str, Any]) -> ScanView: ...


# name -> "module:Class"; detection tries them in this order (most specific first)
READERS: Registry[type] = Registry("scan reader")
READERS.add("generic", "refspatial_gen.sources.scan.readers.generic:GenericReader")
READERS.add("sunrgbd", "refspatial_gen.sources.scan.readers.sunrgbd:SunRGBDReader")
READERS.add("scannet", "refspatial_gen.sources.scan.readers.scannet:ScanNetReader")
READERS.add("colmap", "refspatial_gen.sources.scan.readers.colmap:ColmapReader")
READERS.add("mcap", "refspatial_gen.sources.scan.readers.mcap_reader:McapReader")
READERS.add("usd", "refspatial_gen.sources.scan.readers.usd:UsdReader")
READERS.add("rgbd_trajectory", "refspatial_gen.sources.scan.readers.trajectory:TrajectoryReader")


def get_reader(name: str) -> ScanReader:
    return READERS.get(name)()  # type: ignore[no-any-return]


def detect_reader(root: Path) -> str:
    """The first reader (in registration order) that recognises the folder or file."""
    for name in READERS:
        if get_reader(name).detect(root):
            return name
    raise ValueError(f"no scan reader recognises {root} (known formats: {', '.join(READERS)})")
