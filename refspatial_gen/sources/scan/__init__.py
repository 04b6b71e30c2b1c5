"""The scan source: posed RGB-D frames with oriented 3D boxes from real scans and recordings.

Readers (readers/) parse SUN RGB-D, ScanNet, Open3D/TUM/ICL-NUIM trajectories, COLMAP models, USD stages,
MCAP recordings and the generic scan format (docs/scan.md) into ScanViews; frames.py applies one set of
rules (depth checks, keyframe tests, visibility, masks, gravity) to make Frames.
"""

from refspatial_gen.sources.scan.source import (
    CONFIG_FIELDS,
    ScanSource,
    input_root,
    load_frame,
    parse_unit_key,
    unit_key,
)

__all__ = ["CONFIG_FIELDS", "ScanSource", "input_root", "load_frame", "parse_unit_key", "unit_key"]
