"""The verifier's own view of a frame: raw geometry evaluated through the relation registry's `evaluate`
(never the stored facts or the generator's index), decoded masks, and quantities recomputed from the stored
boxes, depth and cameras. `Run` re-evaluates a stored program step by step with each op's `verify`.

Why a second code path: a check that shares the generator's code shares its bugs (see qa/verify.py).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from refspatial_gen.core.geometry import Box3D, box_distance
from refspatial_gen.core.model import Frame, ObjectInstance, QAPair, SceneGraph
from refspatial_gen.graph.relations import REGISTRY

LENGTH_ABS_TOL = 0.01  # m: recomputed lengths (sampled box distances) may differ by this ...
LENGTH_REL_TOL = 0.03  # ... or by this share
ANGLE_TOL = math.radians(1.0)


class Undecided(Exception):
    """A relation the stored program asks is inside its margin on the raw geometry."""


class Fail(Exception):
    """The stored program does not re-evaluate (not unique, no winner, unknown op...)."""


def one(x: Any) -> int:
    if isinstance(x, (frozenset, set, list)):
        if len(x) != 1:
            raise Fail(f"the described object is not unique: {sorted(x)}")
        return int(next(iter(x)))
    return int(x)


class World:
    """Raw geometry of one frame, evaluated on demand through the relation registry."""

    def __init__(self, frame: Frame, graph: SceneGraph) -> None:
        from refspatial_gen.graph import geometry

        self.frame, self.graph = frame, graph
        cfg: dict[str, Any] = {}
        if graph.meta.get("scale"):
            cfg["scale"] = graph.meta["scale"]
        if graph.meta.get("thresholds"):
            cfg["thresholds"] = graph.meta["thresholds"]
        self.geom = geometry(frame, cfg)
        self.nodes = {n.object_id: n for n in graph.nodes}
        for i, o in enumerate(frame.objects):  # fronts the graph withheld (cut, half seen: graph/visibility.py)
            n = self.nodes.get(o.id)  # stay unknown here too; qa/verify_truth.py checks each withholding's cause
            if n is not None and n.attributes.get("front_check"):
                self.geom.fronts[i] = np.nan
                self.geom.has_front[i] = False
        self.objects = {o.id: o for o in frame.objects}
        self.used: list[str] = []
        self._masks: dict[int, np.ndarray] = {}

    def holds(self, rel: str, *args: Any) -> bool:
        from refspatial_gen.graph.relations import evaluate

        if rel == "between":  # the verifier's own rule (qa/verify_between.py), not the generator's arrays
            from refspatial_gen.qa.verify_between import between_holds

            h = between_holds(self, *(int(x) for x in args))
            if h is None:
                raise Undecided(f"between{tuple(args)} is inside its margin")
            return h
        if rel in ("above_world", "below_world"):  # the verifier's own rule (qa/verify_vertical.py)
            return self._vertical(rel, int(args[0]), int(args[1]))
        if rel in ("inside", "outside"):  # the verifier's own share and receptacle rule (qa/verify_inside.py)
            from refspatial_gen.qa.verify_inside import inside_holds

            h = inside_holds(self, int(args[0]), int(args[1]))
            if h is None:
                raise Undecided(f"{rel}{tuple(args)} is inside its margin or no receptacle holds it")
            return h if rel == "inside" else not h
        f = evaluate(self.geom, rel, *args)
        if f.holds is not None and len(args) == 2:  # the verifier's own span check (qa/verify_span.py)
            from refspatial_gen.qa.verify_span import spanned

            why = spanned(self, rel, int(args[0]), int(args[1]))
            if why:
                raise Undecided(f"{rel}{tuple(args)}: {why}")
        if f.holds is None:
            raise Undecided(f"{rel}{tuple(args)} is inside its margin (value {f.value:.4f}, margin {f.margin:.4f})")
        return bool(f.holds)

    def _vertical(self, rel: str, a: int, b: int) -> bool:
        from refspatial_gen.qa.verify_vertical import above_world_holds

        h = above_world_holds(self, a, b) if rel == "above_world" else above_world_holds(self, b, a)
        if h is None:
            raise Undecided(f"{rel}{(a, b)} is neither over nor clearly higher (qa/verify_vertical.py)")
        return h

    def mask(self, oid: int) -> np.ndarray:
        m = self._masks.get(oid)
        if m is None:
            o = self.objects[oid]
            m = (
                o.mask.decode()
                if o.mask is not None
                else np.zeros((self.frame.camera.height, self.frame.camera.width), bool)
            )
            self._masks[oid] = m
        return m

    def on_surface(self, oid: int, sid: str) -> bool:
        n = self.nodes[oid]
        return n.attributes.get("surface") == sid or n.support == sid


# ------------------------------------------------------------------------------------------ numbers
def _size(box: Box3D) -> tuple[float, float, float]:
    fp = box.footprint()
    s = np.linalg.norm(np.roll(fp, -1, axis=0) - fp, axis=1)
    return float(max(s[0], s[1])), float(min(s[0], s[1])), float(box.height)


def _horizontal_front(o: ObjectInstance) -> np.ndarray | None:
    f = o.front_world
    if f is None:
        return None
    h = np.asarray(f[:2], float)
    n = np.linalg.norm(h)
    return None if n < 1e-9 else h / n


def recompute_quantity(world: World, q: str, a: int, b: int | None) -> float:
    """A measured quantity recomputed from the stored boxes, masks, depth and camera (SI units)."""
    fr = world.frame
    oa = world.objects[a]
    if q == "distance":
        return box_distance(oa.box, world.objects[b].box, n=9)  # type: ignore[index]
    if q == "depth":
        d = fr.depth[world.mask(a)]
        d = d[d > 0]
        if len(d) == 0:
            raise Fail("depth: no valid depth pixel in the object's mask")
        return float(np.median(d))
    if q == "height":
        return _size(oa.box)[2]
    if q == "width":
        return _size(oa.box)[0]
    if q == "angle":
        h1, h2 = _horizontal_front(oa), _horizontal_front(world.objects[b])  # type: ignore[index]
        if h1 is None or h2 is None:
            raise Fail("angle: an object has no front direction")
        return float(np.arccos(np.clip(h1 @ h2, -1, 1)))
    cam = fr.camera
    pc = cam.world_to_cam(oa.box.center)[0]
    if q == "rotation_horizontal":
        return float(math.atan2(pc[0], pc[2]))
    if q == "rotation_vertical":  # view-relative tilt after the horizontal turn (camera y points down)
        return float(math.atan2(-pc[1], math.hypot(pc[0], pc[2])))
    raise Fail(f"unknown quantity {q!r}")


class Run:
    """Re-evaluates a stored program on the raw geometry; `drop` skips one step (degeneracy test)."""

    fail = Fail  # ops raise run.fail(message) / run.undecided(message)
    undecided = Undecided
    one = staticmethod(one)

    def __init__(self, world: World, frames: dict[str, Frame], qa: QAPair) -> None:
        self.w, self.frames, self.qa = world, frames, qa

    def ref(self, v: Any, env: dict[str, Any], prev: Any) -> Any:
        if isinstance(v, dict):
            if "step" in v:
                return prev if v["step"] in (None, "prev") else env[v["step"]]
            if "object" in v:
                return int(v["object"])
            if "spot" in v:
                return tuple(v["spot"])
            if "region" in v:
                return v["region"]
            raise Fail(f"unreadable argument {v!r}")
        if isinstance(v, list):
            return [self.ref(x, env, prev) for x in v]
        if v == "all":
            return frozenset(self.w.nodes)
        return v

    def run(self, drop: int | None = None) -> tuple[Any, dict[str, Any]]:
        from refspatial_gen.core.registry import UnknownName
        from refspatial_gen.qa.ops import OPS

        env: dict[str, Any] = {}
        prev = None
        for k, st in enumerate(self.qa.program):
            op, raw = st["op"], st.get("args") or {}
            a = {key: self.ref(v, env, prev) for key, v in raw.items()}
            try:
                impl = OPS[op]
            except UnknownName:
                raise Fail(f"unknown op {op!r}") from None
            if k == drop:
                if not impl.droppable:
                    raise Fail("not droppable")
                val = impl.verify_dropped(a, prev)
            else:
                val = impl.verify(self, a, prev, st)
            env[st["as"]] = val
            prev = val
        return prev, env

    @staticmethod
    def input_set(a: dict[str, Any]) -> Any:
        """A step's stored input set (None when the record has none)."""
        return frozenset(a["in"]) if isinstance(a.get("in"), (frozenset, list, set)) else None

    @staticmethod
    def anchored(rel: str) -> bool:
        return REGISTRY[rel].qa == "anchored"

    def quantity(self, q: str, a: int, b: int | None) -> float:
        return recompute_quantity(self.w, q, a, b)

    def most(self, cands: list[Any], rel: str, anchor: Any) -> Any:
        """The candidate that decidedly wins against every other. Comparisons between two losers may be
        undecided (they do not change the answer); an undecided comparison of the winner may not."""
        w = self.w
        winners, undecided = [], []
        for x in cands:
            try:
                if all(
                    w.holds(rel, x, y, anchor) if self.anchored(rel) else w.holds(rel, x, y) for y in cands if y != x
                ):
                    winners.append(x)
            except Undecided as e:
                undecided.append(str(e))
        if len(winners) == 1:
            return winners[0]
        if undecided:
            raise Undecided(undecided[0])
        raise Fail(f"no single {rel} winner among {cands}")
