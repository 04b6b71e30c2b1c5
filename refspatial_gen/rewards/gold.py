"""The ground truth a reward reads for one QA pair ("gold"): a small JSON object, built from the stored
sample by `build_gold`, carried inside RFT exports as a JSON string (verl's `ground_truth`, a TRL column).

Fields (`v` = 1):
  qa_id, kind ("points" | "region" | "choice" | "number"), image_size [W, H], answer (the gold answer
  text), reasoning (true when the QA has a gold trace), key_steps [{type, phrase, value}],
  points [[x, y]] normalised gold point (points/region), mask (COCO uncompressed RLE, column-major, of the
  target's visible mask or of the free-space region's visible pixels; points/region),
  options, letter (choice), value (SI: metres or radians), quantity, unit (number).

Why a mask and not only the point: RefSpatial-Bench scores a point as correct when it falls inside the
target's mask (or the free-space region), and about half of a 50 px disc around a gold point lies off a
small object; the region reward and `refspatial-gen eval` read the mask.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from refspatial_gen.core.mask import RLE

GOLD_VERSION = 1


@dataclass
class Gold:
    qa_id: str
    kind: str
    image_size: tuple[int, int]
    answer: str
    reasoning: bool = False
    key_steps: list[dict] = field(default_factory=list)
    points: list[list[float]] = field(default_factory=list)
    mask: dict | None = None
    options: list[str] = field(default_factory=list)
    letter: str | None = None
    value: float | None = None
    quantity: str | None = None
    unit: str | None = None
    _mask_cache: Any = field(default=None, repr=False, compare=False)

    # --------------------------------------------------------------------- JSON
    def to_json(self) -> dict:
        d = {
            "v": GOLD_VERSION,
            "qa_id": self.qa_id,
            "kind": self.kind,
            "image_size": list(self.image_size),
            "answer": self.answer,
            "reasoning": bool(self.reasoning),
            "key_steps": list(self.key_steps),
        }
        if self.kind in ("points", "region"):
            d["points"] = self.points
            d["mask"] = self.mask
        elif self.kind == "choice":
            d["options"] = list(self.options)
            d["letter"] = self.letter
        elif self.kind == "number":
            d.update(value=self.value, quantity=self.quantity, unit=self.unit)
        return d

    def dumps(self) -> str:
        return json.dumps(self.to_json(), sort_keys=True, separators=(",", ":"))

    @classmethod
    def from_json(cls, d: dict) -> Gold:
        if not isinstance(d, dict) or "kind" not in d or "image_size" not in d:
            raise ValueError("gold must be an object with at least 'kind' and 'image_size'")
        if d.get("v", GOLD_VERSION) != GOLD_VERSION:
            raise ValueError(f"gold version {d.get('v')!r} not supported (this code reads {GOLD_VERSION})")
        return cls(
            qa_id=str(d.get("qa_id", "")),
            kind=d["kind"],
            image_size=tuple(int(x) for x in d["image_size"]),
            answer=str(d.get("answer", "")),
            reasoning=bool(d.get("reasoning", False)),
            key_steps=list(d.get("key_steps") or []),
            points=[list(p) for p in d.get("points") or []],
            mask=d.get("mask"),
            options=list(d.get("options") or []),
            letter=d.get("letter"),
            value=None if d.get("value") is None else float(d["value"]),
            quantity=d.get("quantity"),
            unit=d.get("unit"),
        )

    # --------------------------------------------------------------------- mask
    def mask_array(self) -> np.ndarray | None:
        """The decoded (H, W) bool mask, cached."""
        if self.mask is None:
            return None
        if self._mask_cache is None:
            m = RLE.from_json(self.mask).decode()
            ys, xs = np.nonzero(m)
            self._mask_cache = (m, np.column_stack([xs + 0.5, ys + 0.5]).astype(np.float64))
        return self._mask_cache[0]

    def mask_centres(self) -> np.ndarray:
        """(N, 2) pixel centres of the mask, for distances to it."""
        self.mask_array()
        return np.zeros((0, 2)) if self._mask_cache is None else self._mask_cache[1]


def coerce_gold(gold: Gold | dict | str) -> Gold:
    """A Gold from itself, its JSON object, or its JSON string (strings are cached: trainers pass the same
    ground truth once per generation)."""
    if isinstance(gold, Gold):
        return gold
    if isinstance(gold, str):
        return _gold_from_str(gold)
    return Gold.from_json(gold)


@lru_cache(maxsize=512)
def _gold_from_str(s: str) -> Gold:
    try:
        d = json.loads(s)
    except json.JSONDecodeError as e:
        raise ValueError(f"ground truth is not JSON: {e}") from e
    return Gold.from_json(d)


# ----------------------------------------------------------------------------- building from a sample
def build_gold(qa: dict, frame_meta: dict, graph: dict | None = None, depth: np.ndarray | None = None) -> Gold:
    """Gold for one stored QA pair (`QAPair.to_json()`), given the frame it asks about (`Frame.meta_json()`),
    that frame's scene graph and depth map (both needed for free-space regions only).

    Raises ValueError when the stored data cannot give the ground truth (e.g. a target without a mask).
    """
    s = qa.get("answer_struct") or {}
    kind = s.get("kind")
    W, H = (int(x) for x in qa["image_size"])
    g = Gold(
        qa_id=qa["qa_id"],
        kind=kind,
        image_size=(W, H),
        answer=qa["answer"],
        reasoning=bool(qa.get("trace")),
        key_steps=[dict(k) for k in qa.get("key_steps") or []],
    )
    if kind == "points":
        g.points = [list(map(float, p)) for p in s.get("points") or []]
        oid = (s.get("object_ids") or qa.get("targets") or [None])[0]
        obj = next((o for o in frame_meta["objects"] if o["id"] == oid), None)
        if obj is None or obj.get("mask") is None:
            raise ValueError(f"{qa['qa_id']}: target object {oid} has no mask in frame {frame_meta['frame_id']}")
        g.mask = obj["mask"]
    elif kind == "region":
        from refspatial_gen.rewards.regions import region_mask

        g.points = [list(map(float, p)) for p in s.get("points") or []]
        if graph is None or depth is None:
            raise ValueError(f"{qa['qa_id']}: a free-space answer needs the scene graph and the depth map")
        g.mask = RLE.encode(region_mask(frame_meta, graph, s.get("region") or {}, depth)).to_json()
    elif kind == "choice":
        g.options = [str(o) for o in s.get("options") or []]
        g.letter = s.get("letter")
    elif kind == "number":
        g.value, g.quantity, g.unit = float(s["value"]), s.get("quantity"), s.get("unit")
    else:
        raise ValueError(f"{qa['qa_id']}: unknown answer kind {kind!r}")
    return g


def gold_text(qa: dict) -> str:
    """What a perfect model writes: the QA's reasoning trace when it has one, else its answer."""
    return qa.get("trace") or qa["answer"]
