"""Core data model shared by every stage: geometry, cameras, masks, frames, scene graphs, QA pairs.

Only numpy is imported here, so every stage (and its tests) can use the model without heavy deps.
"""

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D, rot_z
from refspatial_gen.core.mask import RLE
from refspatial_gen.core.model import (
    Frame,
    FreeSpaceRegion,
    KeyStep,
    Node,
    ObjectInstance,
    QAPair,
    RelationFact,
    Sample,
    SceneGraph,
    SupportSurface,
)

__all__ = [
    "Box3D",
    "Camera",
    "Frame",
    "FreeSpaceRegion",
    "KeyStep",
    "Node",
    "ObjectInstance",
    "QAPair",
    "RLE",
    "RelationFact",
    "Sample",
    "SceneGraph",
    "SupportSurface",
    "rot_z",
]
