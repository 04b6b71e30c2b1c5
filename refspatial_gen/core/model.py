"""The data that crosses stage boundaries: Frame -> SceneGraph -> QAPair, grouped into a Sample.

Every class has `to_json()` / `from_json()`; large arrays (RGB, depth) are not part of the JSON and
travel as compact binary blobs (see `core.serialize`). Nothing is ever pickled.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from refspatial_gen.core.camera import Camera
from refspatial_gen.core.geometry import Box3D
from refspatial_gen.core.mask import RLE


def _vec(v: Any, nd: int = 6) -> list[float] | None:
    return None if v is None else [round(float(x), nd) for x in np.asarray(v).ravel()]


@dataclass(eq=False)
class ObjectInstance:
    """One object in a frame. `id` is unique within the frame (and equals its segmentation id, > 0).

    `front` is a unit vector in the object's box frame (not world) pointing to its semantic front, with
    `front_phrase` naming that side ("the handle side"); None when the source does not know it.
    """

    id: int
    category: str
    box: Box3D
    mask: RLE | None = None
    bbox2d: tuple[float, float, float, float] | None = None  # x0, y0, x1, y1 in pixels (0-based, exclusive max)
    visible_fraction: float = 1.0
    name: str | None = None
    description: str | None = None
    attributes: dict[str, str] = field(default_factory=dict)  # e.g. {"color": "red", "material": "ceramic"}
    front: np.ndarray | None = None
    front_phrase: str | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def front_world(self) -> np.ndarray | None:
        if self.front is None:
            return None
        f = self.box.rotation @ np.asarray(self.front, float)
        return f / np.linalg.norm(f)

    def to_json(self) -> dict[str, Any]:
        return {
            "id": int(self.id),
            "category": self.category,
            "box": self.box.to_json(),
            "mask": None if self.mask is None else self.mask.to_json(),
            "bbox2d": None if self.bbox2d is None else [round(float(x), 3) for x in self.bbox2d],
            "visible_fraction": round(float(self.visible_fraction), 6),
            "name": self.name,
            "description": self.description,
            "attributes": dict(sorted(self.attributes.items())),
            "front": _vec(self.front),
            "front_phrase": self.front_phrase,
            "provenance": self.provenance,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> ObjectInstance:
        return cls(
            id=d["id"],
            category=d["category"],
            box=Box3D.from_json(d["box"]),
            mask=None if d.get("mask") is None else RLE.from_json(d["mask"]),
            bbox2d=None if d.get("bbox2d") is None else tuple(d["bbox2d"]),
            visible_fraction=d.get("visible_fraction", 1.0),
            name=d.get("name"),
            description=d.get("description"),
            attributes=dict(d.get("attributes") or {}),
            front=None if d.get("front") is None else np.array(d["front"]),
            front_phrase=d.get("front_phrase"),
            provenance=dict(d.get("provenance") or {}),
        )


@dataclass(eq=False)
class SupportSurface:
    """A horizontal surface things stand on. `box` is the slab; its top face is the surface. `object_id` is
    set when the surface belongs to an object in `Frame.objects` (e.g. a box lid)."""

    id: str
    kind: str  # "table", "floor", "shelf", "counter", "object"
    box: Box3D
    object_id: int | None = None
    name: str | None = None  # phrase used in text, e.g. "the table"

    @property
    def top_z(self) -> float:
        return self.box.top_z

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "kind": self.kind,
            "box": self.box.to_json(),
            "object_id": self.object_id,
            "name": self.name,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SupportSurface:
        return cls(d["id"], d["kind"], Box3D.from_json(d["box"]), d.get("object_id"), d.get("name"))


@dataclass(eq=False)
class Frame:
    """One calibrated RGB-D view with its objects. `depth` is metric float32, 0 = unknown."""

    frame_id: str
    rgb: np.ndarray  # uint8 HxWx3
    depth: np.ndarray  # float32 HxW metres
    camera: Camera
    objects: list[ObjectInstance]
    surfaces: list[SupportSurface] = field(default_factory=list)
    source: str = "sim"
    scene_id: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def object(self, object_id: int) -> ObjectInstance:
        for o in self.objects:
            if o.id == object_id:
                return o
        raise KeyError(f"frame {self.frame_id} has no object {object_id}")

    def validate(self) -> None:
        """Raise ValueError with a reason when the frame is unusable (the run drops it and counts why)."""
        h, w = self.camera.height, self.camera.width
        if self.rgb.shape != (h, w, 3) or self.rgb.dtype != np.uint8:
            raise ValueError(f"rgb has shape {self.rgb.shape} {self.rgb.dtype}, expected ({h}, {w}, 3) uint8")
        if self.depth.shape != (h, w):
            raise ValueError(f"depth has shape {self.depth.shape}, expected ({h}, {w})")
        if not np.all(np.isfinite(self.depth)):
            raise ValueError("depth has NaN or infinite values")
        if not np.any(self.depth > 0):
            raise ValueError("depth has no valid pixel")
        ids = [o.id for o in self.objects]
        if len(set(ids)) != len(ids):
            raise ValueError("duplicate object ids")

    def meta_json(self) -> dict[str, Any]:
        """Everything but the pixel arrays."""
        return {
            "frame_id": self.frame_id,
            "scene_id": self.scene_id,
            "source": self.source,
            "camera": self.camera.to_json(),
            "objects": [o.to_json() for o in self.objects],
            "surfaces": [s.to_json() for s in self.surfaces],
            "meta": self.meta,
        }

    @classmethod
    def from_meta_json(cls, d: dict[str, Any], rgb: np.ndarray, depth: np.ndarray) -> Frame:
        return cls(
            frame_id=d["frame_id"],
            rgb=rgb,
            depth=depth,
            camera=Camera.from_json(d["camera"]),
            objects=[ObjectInstance.from_json(o) for o in d["objects"]],
            surfaces=[SupportSurface.from_json(s) for s in d.get("surfaces", [])],
            source=d.get("source", "sim"),
            scene_id=d.get("scene_id", ""),
            meta=dict(d.get("meta") or {}),
        )


@dataclass(eq=False)
class Node:
    """A graph node: an object plus derived attributes and its unique referring phrases (shortest first)."""

    object_id: int
    category: str
    attributes: dict[str, Any] = field(default_factory=dict)  # color, size_rank, height_rank, ordinals...
    phrases: list[str] = field(default_factory=list)  # unique referring expressions; empty = not referable
    point: tuple[float, float] | None = None  # normalised answer point (RefSpatial convention)
    support: str | None = None  # id of the supporting surface, or "obj:<id>"

    def to_json(self) -> dict[str, Any]:
        return {
            "object_id": int(self.object_id),
            "category": self.category,
            "attributes": self.attributes,
            "phrases": list(self.phrases),
            "point": None if self.point is None else [round(float(x), 3) for x in self.point],
            "support": self.support,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Node:
        return cls(
            d["object_id"],
            d["category"],
            dict(d.get("attributes") or {}),
            list(d.get("phrases") or []),
            None if d.get("point") is None else tuple(d["point"]),
            d.get("support"),
        )


@dataclass(eq=False)
class RelationFact:
    """An evaluated relation. `holds` is None when the comparison is inside the margin (undecided)."""

    relation: str
    args: tuple[Any, ...]  # object ids (int) or surface ids (str), in the relation's argument order
    holds: bool | None
    value: float  # the metric quantity the decision rests on (metres, radians, fraction, ...)
    margin: float

    def to_json(self) -> dict[str, Any]:
        return {
            "relation": self.relation,
            "args": list(self.args),
            "holds": self.holds,
            "value": round(float(self.value), 6),
            "margin": round(float(self.margin), 6),
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RelationFact:
        return cls(d["relation"], tuple(d["args"]), d["holds"], d["value"], d["margin"])


@dataclass(eq=False)
class FreeSpaceRegion:
    """A free area on a support surface: polygon in world xy at height z, plus one visible answer point."""

    surface_id: str
    kind: str  # "left_of", "right_of", "in_front_of", "behind", "between", "corner", "edge", ...
    anchors: tuple[Any, ...]  # object ids the region is defined relative to
    polygon_xy: list[tuple[float, float]]  # world-frame outline on the surface
    z: float
    area: float  # m^2
    point_world: tuple[float, float, float]
    point: tuple[float, float]  # normalised image point
    label: str = ""  # e.g. "far-left corner", "right edge"

    def to_json(self) -> dict[str, Any]:
        return {
            "surface_id": self.surface_id,
            "kind": self.kind,
            "anchors": list(self.anchors),
            "polygon_xy": [[round(float(x), 5), round(float(y), 5)] for x, y in self.polygon_xy],
            "z": round(float(self.z), 6),
            "area": round(float(self.area), 6),
            "point_world": [round(float(x), 6) for x in self.point_world],
            "point": [round(float(x), 3) for x in self.point],
            "label": self.label,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> FreeSpaceRegion:
        return cls(
            d["surface_id"],
            d["kind"],
            tuple(d["anchors"]),
            [tuple(p) for p in d["polygon_xy"]],
            d["z"],
            d["area"],
            tuple(d["point_world"]),
            tuple(d["point"]),
            d.get("label", ""),
        )


@dataclass(eq=False)
class SceneGraph:
    """The metric scene graph of one frame."""

    frame_id: str
    nodes: list[Node]
    facts: list[RelationFact] = field(default_factory=list)
    free_space: list[FreeSpaceRegion] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)  # thresholds used, scale ("tabletop"/"room"), ...

    def node(self, object_id: int) -> Node:
        for n in self.nodes:
            if n.object_id == object_id:
                return n
        raise KeyError(object_id)

    def to_json(self) -> dict[str, Any]:
        return {
            "frame_id": self.frame_id,
            "nodes": [n.to_json() for n in self.nodes],
            "facts": [f.to_json() for f in self.facts],
            "free_space": [r.to_json() for r in self.free_space],
            "meta": self.meta,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SceneGraph:
        return cls(
            d["frame_id"],
            [Node.from_json(n) for n in d["nodes"]],
            [RelationFact.from_json(f) for f in d.get("facts", [])],
            [FreeSpaceRegion.from_json(r) for r in d.get("free_space", [])],
            dict(d.get("meta") or {}),
        )


@dataclass(eq=False)
class KeyStep:
    """One perceptual step of a reasoning trace, with its ground truth (for process rewards)."""

    type: str  # "Position" | "Orientation" | "Size"
    phrase: str  # exact target phrase used in the trace
    value: list[float]  # normalised (x, y) | unit vector (camera frame) | Size: [one length in metres]
    measure: str = ""  # Size only: which length `value` is ("height", "width", "volume": side of an equal cube)
    extent: list[float] | None = None  # Size only: the full 3-D size (larger / smaller horizontal, height)

    def to_json(self) -> dict[str, Any]:
        size = {"measure": self.measure, "extent": _vec(self.extent, 3)} if self.measure else {}  # Size steps
        return {"type": self.type, "phrase": self.phrase, "value": _vec(self.value, 3), **size}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> KeyStep:
        return cls(**{**d, "value": list(d["value"])})  # type, phrase, value [, measure, extent]


@dataclass(eq=False)
class QAPair:
    """One question with its checked answer, reasoning trace and provenance."""

    qa_id: str
    family: str  # locate, identify, placement, choice, quantitative, visual_choice, multiview
    template: str
    question: str
    answer: str
    answer_struct: dict[str, Any]  # {"kind": "points"|"region"|"choice"|"number", ...}
    relations: list[str]
    steps: int
    frame_ids: list[str]
    image_size: tuple[int, int]  # (width, height)
    program: list[dict[str, Any]] = field(default_factory=list)
    trace: str = ""  # "<think>...</think><answer>...</answer>" for multi-step questions
    key_steps: list[KeyStep] = field(default_factory=list)
    checks: list[str] = field(default_factory=list)  # names of the checks it passed
    targets: list[int] = field(default_factory=list)  # object ids the answer refers to (for verification)

    def to_json(self) -> dict[str, Any]:
        return {
            "qa_id": self.qa_id,
            "family": self.family,
            "template": self.template,
            "question": self.question,
            "answer": self.answer,
            "answer_struct": self.answer_struct,
            "relations": list(self.relations),
            "steps": int(self.steps),
            "frame_ids": list(self.frame_ids),
            "image_size": list(self.image_size),
            "program": self.program,
            "trace": self.trace,
            "key_steps": [k.to_json() for k in self.key_steps],
            "checks": list(self.checks),
            "targets": [int(t) for t in self.targets],
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> QAPair:
        return cls(
            d["qa_id"],
            d["family"],
            d["template"],
            d["question"],
            d["answer"],
            d["answer_struct"],
            list(d["relations"]),
            d["steps"],
            list(d["frame_ids"]),
            tuple(d["image_size"]),
            list(d.get("program") or []),
            d.get("trace", ""),
            [KeyStep.from_json(k) for k in d.get("key_steps") or []],
            list(d.get("checks") or []),
            list(d.get("targets") or []),
        )


@dataclass(eq=False)
class Sample:
    """The unit stored in a shard: one frame (or a multi-view group) with its graphs and QA pairs."""

    sample_id: str
    frames: list[Frame]
    graphs: list[SceneGraph]
    qa: list[QAPair]
    unit_key: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
