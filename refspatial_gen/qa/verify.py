"""Independent re-check of stored QA pairs (`refspatial-gen verify DIR`, `verify_sample`).

Why a second code path: a check that shares the generator's code shares its bugs. The verifier reads
only what a shard stores (frames, scene graphs, QA pairs with their executed programs) and re-derives
every answer on its own: relations are re-evaluated on the frame's raw geometry through the relation
registry's `evaluate` (not the stored facts or the generator's index), phrases are re-resolved by the
graph's independent resolver, points are tested against decoded masks, free points against the
surface and depth map, and numbers are recomputed from the stored 3D boxes with core.geometry.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from refspatial_gen.core.geometry import box_distance
from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import Frame, QAPair, Sample, SceneGraph

LETTERS = "ABCDEFGH"
LENGTH_ABS_TOL = 0.01  # m: recomputed lengths (sampled box distances) may differ by this ...
LENGTH_REL_TOL = 0.03  # ... or by this share
ANGLE_TOL = math.radians(1.0)
KEY_TOL = 1.5e-3  # key-step values are rounded to 3 decimals
ORDERED = {"left", "right", "front", "behind", "above_world", "below_world", "above_image", "below_image", "tall",
           "short", "big", "small", "wide", "thin"}
ANCHORED = {"close", "far"}
# the formats.md step rule, restated here on purpose (not imported from the generator)
_STEP_WEIGHTS = {"relate": 2, "at": 2, "is_at": 2, "between": 3, "camera_turn": 1}


class _Undecided(Exception):
    pass


class _Fail(Exception):
    pass


def _one(x: Any) -> int:
    if isinstance(x, (frozenset, set, list)):
        if len(x) != 1:
            raise _Fail(f"the described object is not unique: {sorted(x)}")
        return int(next(iter(x)))
    return int(x)


def _steps_of(program: list[dict]) -> int:
    n = 0
    for st in program:
        op, a = st.get("op"), st.get("args") or {}
        if op in _STEP_WEIGHTS:
            n += _STEP_WEIGHTS[op]
        elif op == "superlative":
            n += 2 if a.get("anchor") is not None else 0
        elif op == "free_space":
            n += 3 if a.get("anchors") is not None else (1 if a.get("region") is not None else 2)
        elif op == "compare":
            n += 3 if a.get("anchor") is not None else 2
        elif op == "measure":
            n += 1 if a.get("to") is not None else 0
        elif op == "choose":
            n += 3 if a.get("anchor") is not None else 1
    return max(1, n)


class _World:
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
        self.objects = {o.id: o for o in frame.objects}
        self.used: list[str] = []
        self._masks: dict[int, np.ndarray] = {}

    def holds(self, rel: str, *args) -> bool:
        from refspatial_gen.graph.relations import evaluate

        f = evaluate(self.geom, rel, *args)
        if f.holds is None:
            raise _Undecided(f"{rel}{tuple(args)} is inside its margin (value {f.value:.4f}, margin {f.margin:.4f})")
        return bool(f.holds)

    def mask(self, oid: int) -> np.ndarray:
        m = self._masks.get(oid)
        if m is None:
            o = self.objects[oid]
            m = o.mask.decode() if o.mask is not None else np.zeros((self.frame.camera.height, self.frame.camera.width), bool)
            self._masks[oid] = m
        return m

    def on_surface(self, oid: int, sid: str) -> bool:
        n = self.nodes[oid]
        return n.attributes.get("surface") == sid or n.support == sid


# ------------------------------------------------------------------------------------------ numbers
def _size(box) -> tuple[float, float, float]:
    fp = box.footprint()
    s = np.linalg.norm(np.roll(fp, -1, axis=0) - fp, axis=1)
    return float(max(s[0], s[1])), float(min(s[0], s[1])), float(box.height)


def _horizontal_front(o) -> np.ndarray | None:
    f = o.front_world
    if f is None:
        return None
    h = np.asarray(f[:2], float)
    n = np.linalg.norm(h)
    return None if n < 1e-9 else h / n


def recompute_quantity(world: _World, q: str, a: int, b: int | None) -> float:
    """A measured quantity recomputed from the stored boxes, masks, depth and camera (SI units)."""
    fr = world.frame
    oa = world.objects[a]
    if q == "distance":
        return box_distance(oa.box, world.objects[b].box, n=9)
    if q == "depth":
        d = fr.depth[world.mask(a)]
        d = d[d > 0]
        if len(d) == 0:
            raise _Fail("depth: no valid depth pixel in the object's mask")
        return float(np.median(d))
    if q == "height":
        return _size(oa.box)[2]
    if q == "width":
        return _size(oa.box)[0]
    if q == "angle":
        h1, h2 = _horizontal_front(oa), _horizontal_front(world.objects[b])
        if h1 is None or h2 is None:
            raise _Fail("angle: an object has no front direction")
        return float(np.arccos(np.clip(h1 @ h2, -1, 1)))
    cam = fr.camera
    pc = cam.world_to_cam(oa.box.center)[0]
    if q == "rotation_horizontal":
        return float(math.atan2(pc[0], pc[2]))
    if q == "rotation_vertical":
        fwd = cam.world_from_cam[:3, 2].copy()
        fwd[2] = 0.0
        fwd /= np.linalg.norm(fwd)
        d = oa.box.center - cam.position
        return float(math.atan2(d[2], d @ fwd))
    raise _Fail(f"unknown quantity {q!r}")


def _close(a: float, b: float, q: str) -> bool:
    if q in ("angle", "rotation_horizontal", "rotation_vertical"):
        return abs(a - b) <= ANGLE_TOL
    return abs(a - b) <= max(LENGTH_ABS_TOL, LENGTH_REL_TOL * max(abs(a), abs(b)))


def camera_turn(f1: Frame, f2: Frame, axis: str) -> float:
    a1, a2 = f1.camera.world_from_cam[:3, 2], f2.camera.world_from_cam[:3, 2]
    if axis == "horizontal":
        d = math.atan2(a2[1], a2[0]) - math.atan2(a1[1], a1[0])
        return (d + math.pi) % (2 * math.pi) - math.pi
    return math.asin(a2[2] / np.linalg.norm(a2)) - math.asin(a1[2] / np.linalg.norm(a1))


# ------------------------------------------------------------------------------------------ program
class _Run:
    """Re-evaluates a stored program on the raw geometry; `drop` skips one step (degeneracy test)."""

    def __init__(self, world: _World, frames: dict[str, Frame], qa: QAPair) -> None:
        self.w, self.frames, self.qa = world, frames, qa

    def ref(self, v: Any, env: dict, prev: Any) -> Any:
        if isinstance(v, dict):
            if "step" in v:
                return prev if v["step"] in (None, "prev") else env[v["step"]]
            if "object" in v:
                return int(v["object"])
            if "spot" in v:
                return tuple(v["spot"])
            if "region" in v:
                return v["region"]
            raise _Fail(f"unreadable argument {v!r}")
        if isinstance(v, list):
            return [self.ref(x, env, prev) for x in v]
        if v == "all":
            return frozenset(self.w.nodes)
        return v

    def run(self, drop: int | None = None) -> tuple[Any, dict]:
        env: dict[str, Any] = {}
        prev = None
        for k, st in enumerate(self.qa.program):
            op, raw = st["op"], st.get("args") or {}
            a = {key: self.ref(v, env, prev) for key, v in raw.items()}
            if k == drop:
                if op in ("relate", "between", "at", "superlative", "ordinal"):
                    val = frozenset(a.get("in", prev))
                elif op in ("compare", "is_at"):
                    val = None
                else:
                    raise _Fail("not droppable")
            else:
                val = self.step(op, a, prev, env, st)
            env[st["as"]] = val
            prev = val
        return prev, env

    def step(self, op: str, a: dict, prev: Any, env: dict, st: dict) -> Any:
        w = self.w
        s = frozenset(a["in"]) if isinstance(a.get("in"), (frozenset, list, set)) else None
        if op == "filter":
            s = s if s is not None else frozenset(w.nodes)
            if "category" in a:
                s = frozenset(i for i in s if w.nodes[i].category == a["category"])
            if "color" in a:
                s = frozenset(i for i in s if w.nodes[i].attributes.get("color") == a["color"])
            if "on" in a:
                s = frozenset(i for i in s if w.on_surface(i, a["on"]))
            return s
        if op == "relate":
            return frozenset(x for x in s if x != a["anchor"] and w.holds(a["relation"], x, a["anchor"]))
        if op == "at":
            kind, sid, label = a["spot"]
            return frozenset(x for x in s if w.holds(kind, x, sid, label))
        if op == "is_at":
            kind, sid, label = a["spot"]
            return w.holds(kind, a["a"], sid, label)
        if op == "between":
            b, c = a["anchors"]
            return frozenset(x for x in s if x not in (b, c) and w.holds("between", x, b, c))
        if op == "superlative":
            anchor = a.get("anchor")
            cands = sorted(x for x in s if x != anchor)
            return self._most(cands, a["relation"], anchor)
        if op == "ordinal":
            cands = sorted(s)
            n = len(cands)
            wins = {x: sum(1 for y in cands if y != x and w.holds(a["relation"], x, y)) for x in cands}
            hit = [x for x in cands if wins[x] == n - int(a["rank"])]
            if len(hit) != 1:
                raise _Fail(f"ordinal: no unique rank {a['rank']} among {cands}")
            return hit[0]
        if op == "locate":
            x = a.get("of", prev)
            if isinstance(x, (frozenset, set, list)):
                if len(x) != 1:
                    raise _Fail(f"the described object is not unique: {sorted(x)}")
                x = next(iter(x))
            return ("object", int(x))
        if op == "free_space":
            return ("free", st.get("out", {}).get("region") or a.get("region"))
        if op == "compare":
            rel, x, y = a["relation"], _one(a["a"]), _one(a["b"])
            if rel in ANCHORED:
                return w.holds(rel, x, y, a["anchor"])
            return w.holds(rel, x, y)
        if op == "all":
            vals = [v for v in a["of"] if v is not None]
            if not vals:
                raise _Fail("all: nothing left")
            return all(vals)
        if op == "measure":
            x = a.get("of", prev)
            if isinstance(x, (frozenset, set, list)):
                if len(x) != 1:
                    raise _Fail(f"measured object is not unique: {sorted(x)}")
                x = next(iter(x))
            return ("number", a["quantity"], recompute_quantity(w, a["quantity"], int(x), a.get("to")))
        if op == "mark":
            marks = [int(m) for m in st.get("out") or []]
            for m in marks:
                if m not in w.objects or w.objects[m].mask is None:
                    raise _Fail(f"marked object {m} is not a visible object of the frame")
            return marks
        if op == "choose":
            opts = list(a["options"])
            rel, anchor = a["relation"], a.get("anchor")
            if a.get("mode") == "which" and rel not in ANCHORED:
                sat = [o for o in opts if w.holds(rel, o, anchor)]
                if len(sat) != 1:
                    raise _Fail(f"choose which: {len(sat)} options satisfy {rel}")
                return ("option", sat[0])
            return ("option", self._most(opts, rel, anchor))
        if op == "camera_turn":
            fids = self.qa.frame_ids
            if len(fids) != 2:
                raise _Fail("camera_turn needs two frames")
            d = camera_turn(self.frames[fids[0]], self.frames[fids[1]], a["axis"])
            words = ("left", "right") if a["axis"] == "horizontal" else ("up", "down")
            if abs(d) < math.radians(2.0):
                raise _Undecided(f"camera turn {math.degrees(d):.2f} degrees is too small to tell")
            return ("option", words[0] if d > 0 else words[1])
        raise _Fail(f"unknown op {op!r}")

    def _most(self, cands: list, rel: str, anchor: Any) -> Any:
        """The candidate that decidedly wins against every other. Comparisons between two losers may be
        undecided (they do not change the answer); an undecided comparison of the winner may not."""
        w = self.w
        winners, undecided = [], []
        for x in cands:
            try:
                if all(w.holds(rel, x, y, anchor) if rel in ANCHORED else w.holds(rel, x, y)
                       for y in cands if y != x):
                    winners.append(x)
            except _Undecided as e:
                undecided.append(str(e))
        if len(winners) == 1:
            return winners[0]
        if undecided:
            raise _Undecided(undecided[0])
        raise _Fail(f"no single {rel} winner among {cands}")


# ------------------------------------------------------------------------------------------ checks
_POINTS = re.compile(r"\(\s*(-?[0-9.]+)\s*,\s*(-?[0-9.]+)\s*\)")
_TRACE_LINE = re.compile(r"^\[(Position|Orientation|Size)\] \[(.+)\]: \(([^)]*)\)$")


def _answer_key(v: Any) -> Any:
    if isinstance(v, frozenset):
        return ("object", next(iter(v))) if len(v) == 1 else ("set", tuple(sorted(v)))
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return ("object", int(v))
    if isinstance(v, tuple) and v and v[0] == "free":
        return ("free", str(v[1]))
    if isinstance(v, tuple) and v and v[0] == "number":
        return ("number", round(v[2], 9))
    return v


def verify_qa(qa: QAPair, frames: dict[str, Frame], graphs: dict[str, SceneGraph],
              worlds: dict[str, _World], order: list[str] | None = None) -> list[str]:
    """Reasons this QA pair fails (empty when it passes). `order`: the sample's frame ids in stored order
    (drawn marks name their image by position in it)."""
    problems: list[str] = []
    if not qa.frame_ids or any(f not in frames or f not in graphs for f in qa.frame_ids):
        return [f"frame ids {qa.frame_ids} not in the sample"]
    fid = qa.frame_ids[0]
    frame, graph = frames[fid], graphs[fid]
    if fid not in worlds:
        worlds[fid] = _World(frame, graph)
    w = worlds[fid]
    if tuple(qa.image_size) != (frame.camera.width, frame.camera.height):
        problems.append(f"image_size {list(qa.image_size)} is not the frame's {[frame.camera.width, frame.camera.height]}")
    if qa.family == "point_depth":  # built-in camera-frame questions: no program, re-checked on the depth map
        from refspatial_gen.qa.verify_pointdepth import verify_point_depth
        return problems + verify_point_depth(qa, frame)
    # --- step count
    if not 1 <= qa.steps <= 5:
        problems.append(f"step count {qa.steps} out of range 1..5")
    if qa.program and _steps_of(qa.program) != qa.steps:
        problems.append(f"step count {qa.steps} but the program counts {_steps_of(qa.program)}")
    # --- phrases
    problems += _check_phrases(qa, graph, frame)
    # --- program re-evaluation, margins, degeneracy
    run = _Run(w, frames, qa)
    final = None
    try:
        final, env = run.run()
    except _Undecided as e:
        problems.append(f"relation asked inside its margin: {e}")
    except _Fail as e:
        problems.append(f"program does not re-evaluate: {e}")
    except (KeyError, TypeError, ValueError, IndexError) as e:
        problems.append(f"program record unreadable: {type(e).__name__}: {e}")
    if final is not None:
        for k, st in enumerate(qa.program):
            if st["op"] not in ("relate", "between", "at", "superlative", "ordinal", "compare", "is_at"):
                continue
            try:
                alt, _ = run.run(drop=k)
            except (_Undecided, _Fail):
                continue
            if _answer_key(alt) == _answer_key(final):
                problems.append(f"degenerate step {k + 1} ({st['op']}): removing it leaves the answer unchanged")
        for k, st in enumerate(qa.program):
            stored, got = st.get("out"), env.get(st["as"])
            if isinstance(got, frozenset) and isinstance(stored, list) and sorted(got) != sorted(stored):
                problems.append(f"step {k + 1} ({st['op']}) stored {sorted(stored)} but re-evaluates to {sorted(got)}")
        problems += _check_answer(qa, final, w, frame, graph)
    problems += _check_marks(qa, w, order if order is not None else list(frames))
    # --- trace and key steps
    problems += _check_trace(qa, w)
    return problems


def _check_phrases(qa: QAPair, graph: SceneGraph, frame: Frame) -> list[str]:
    from refspatial_gen.graph.resolve import resolve_phrase

    out = []
    seen = set()
    q = qa.question.lower()
    for st in qa.program:
        for v in _walk(st.get("args") or {}):
            if isinstance(v, dict) and "phrase" in v and "object" in v:
                key = (v["phrase"], v["object"])
                if key in seen:
                    continue
                seen.add(key)
                ids = resolve_phrase(v["phrase"], graph)
                if list(ids) != [int(v["object"])]:
                    out.append(f"phrase {v['phrase']!r} resolves to {list(ids)}, not to object {v['object']} "
                               "(not a unique reference)")
                if v["phrase"].lower() not in q:
                    out.append(f"phrase {v['phrase']!r} does not appear in the question")
    return out


def _walk(x: Any):
    if isinstance(x, dict):
        yield x
        for v in x.values():
            yield from _walk(v)
    elif isinstance(x, list):
        for v in x:
            yield from _walk(v)


def _check_answer(qa: QAPair, final: Any, w: _World, frame: Frame, graph: SceneGraph) -> list[str]:
    s = qa.answer_struct or {}
    kind = s.get("kind")
    W, H = frame.camera.width, frame.camera.height
    out: list[str] = []
    if kind in ("points", "region"):
        pts = s.get("points") or []
        text_pts = [(float(x), float(y)) for x, y in _POINTS.findall(qa.answer)]
        if len(pts) != 1 or len(text_pts) != 1:
            return [f"expected one answer point, got {pts} / {qa.answer!r}"]
        p = (float(pts[0][0]), float(pts[0][1]))
        if abs(p[0] - text_pts[0][0]) > 1e-9 or abs(p[1] - text_pts[0][1]) > 1e-9:
            out.append(f"answer text {qa.answer!r} differs from the structured point {p}")
        if not (0.0 <= p[0] <= 1.0 and 0.0 <= p[1] <= 1.0):
            out.append(f"answer point {p} outside [0, 1]")
        if kind == "points":
            if not (isinstance(final, tuple) and final[0] == "object"):
                return out + [f"program gives {final!r}, not an object"]
            oid = final[1]
            if list(s.get("object_ids") or []) != [oid] or list(qa.targets) != [oid]:
                out.append(f"answer names object {s.get('object_ids')} / targets {qa.targets}, the program gives {oid}")
            x, y = denormalise_point(p[0], p[1], W, H)
            if not w.mask(oid)[y, x]:
                out.append(f"answer point {p} (pixel {x},{y}) is outside the visible mask of object {oid}")
        else:
            from refspatial_gen.graph.freespace import check_free_point

            reg = _find_region(graph, s.get("region") or {})
            if reg is None:
                out.append(f"free-space region {s.get('region')} is not in the scene graph")
            else:
                out += [f"free point {p}: {m}" for m in check_free_point(frame, graph, reg, p)]
        return out
    if kind == "choice":
        letter = s.get("letter")
        opts = list(s.get("options") or [])
        m = re.match(r"^\(([A-H])\)(?: (.*))?$", qa.answer)
        if not m or m.group(1) != letter or letter not in LETTERS[:max(1, len(opts))]:
            return [f"answer {qa.answer!r} does not match letter {letter!r} of {len(opts)} options"]
        k = LETTERS.index(letter)
        if m.group(2) is not None and m.group(2) != opts[k]:
            out.append(f"answer text {m.group(2)!r} is not option {letter} ({opts[k]!r})")
        if isinstance(final, bool):
            if opts[k] != ("yes" if final else "no"):
                out.append(f"answer is {opts[k]!r} but the relation re-evaluates to {final}")
            if sorted(opts) != ["no", "yes"]:
                out.append(f"yes/no options are {opts}")
        elif isinstance(final, tuple) and final[0] == "option":
            if "marks" in s:
                got = s["marks"][k]["object_id"] if k < len(s["marks"]) else None
            elif "option_ids" in s:
                got = s["option_ids"][k]
            else:
                got = opts[k]
            if got != final[1]:
                out.append(f"answer {letter} names {got!r} but the re-evaluated choice is {final[1]!r}")
        else:
            out.append(f"choice answer but the program gives {final!r}")
        for i, o in enumerate(opts):
            if o and f"({LETTERS[i]}) {o}" not in qa.question:
                out.append(f"option ({LETTERS[i]}) {o!r} is not written in the question")
        return out
    if kind == "number":
        if not (isinstance(final, tuple) and final[0] == "number"):
            return [f"number answer but the program gives {final!r}"]
        q, got = final[1], final[2]
        v = float(s.get("value", float("nan")))
        if not _close(v, got, q):
            out.append(f"{q}: answer {v:.4f} but the geometry gives {got:.4f}")
        nums = re.findall(r"-?[0-9]+(?:\.[0-9]+)?", qa.answer)
        if not nums:
            out.append(f"answer text {qa.answer!r} has no number")
        else:
            t = float(nums[0])
            if "centimeter" in qa.answer:
                t /= 100.0
            elif "degree" in qa.answer:
                t = math.radians(t)
                if qa.answer.startswith("rotate") and re.search(r"rotate (left|down)", qa.answer):
                    t = -t
            tol = 0.006 if "meter" in qa.answer and "centi" not in qa.answer else (0.0051 if "centi" in qa.answer
                                                                                 else math.radians(0.051))
            ref = abs(v) if q == "angle" else v
            if abs(t - ref) > tol:
                out.append(f"answer text {qa.answer!r} does not render the value {v:.4f}")
        return out
    return [f"unknown answer kind {kind!r}"]


def _check_marks(qa: QAPair, w: _World, order: list[str]) -> list[str]:
    """Drawn marks belong on the asked image: each names the position of the QA's frame in the sample, an
    object of that frame, its 2D box as stored, and (when given) a point inside that object's visible mask."""
    from refspatial_gen.core.mask import denormalise_point

    out: list[str] = []
    W, H = w.frame.camera.width, w.frame.camera.height
    for m in (qa.answer_struct or {}).get("marks") or []:
        label, view = m.get("label"), m.get("view", 0)
        if not isinstance(view, int) or not 0 <= view < len(order) or order[view] != qa.frame_ids[0]:
            out.append(f"mark ({label}) is drawn on view {view!r}, not on the asked frame {qa.frame_ids[0]}")
            continue
        oid = m.get("object_id")
        o = w.objects.get(oid)
        if o is None:
            out.append(f"mark ({label}) names object {oid!r}, which is not in the frame")
            continue
        box = m.get("box")
        if box is not None and (o.bbox2d is None or any(abs(float(a) - float(b)) > 0.051 for a, b in zip(box, o.bbox2d))):
            out.append(f"mark ({label}) box {box} is not object {oid}'s 2D box")
        pt = m.get("point")
        if pt is not None:
            x, y = denormalise_point(float(pt[0]), float(pt[1]), W, H)
            if not w.mask(oid)[y, x]:
                out.append(f"mark ({label}) point {pt} is outside object {oid}'s visible mask")
    return out


def _find_region(graph: SceneGraph, r: dict):
    for reg in graph.free_space:
        if reg.surface_id == r.get("surface_id") and reg.kind == r.get("kind") \
                and list(reg.anchors) == list(r.get("anchors") or []) and reg.label == r.get("label", reg.label):
            return reg
    return None


def _check_trace(qa: QAPair, w: _World) -> list[str]:
    out: list[str] = []
    if qa.steps >= 2 and not qa.trace:
        return ["multi-step question without a reasoning trace"]
    if qa.trace:
        m = re.match(r"^<think>(.*)</think><answer>(.*)</answer>$", qa.trace, re.S)
        if not m:
            return ["trace is not <think>...</think><answer>...</answer>"]
        if m.group(2) != qa.answer:
            out.append("trace answer differs from the answer")
        lines = [ln for ln in m.group(1).split("\n") if ln.strip()]
        if len(lines) != len(qa.key_steps):
            out.append(f"trace has {len(lines)} steps, key_steps {len(qa.key_steps)}")
        for ln, ks in zip(lines, qa.key_steps):
            mm = _TRACE_LINE.match(ln)
            if not mm:
                out.append(f"trace line {ln!r} is not '[Type] [phrase]: (values)'")
                continue
            vals = [float(x) for x in mm.group(3).split(",")]
            if mm.group(1) != ks.type or mm.group(2) != ks.phrase or len(vals) != len(ks.value) \
                    or any(abs(a - b) > 1e-9 for a, b in zip(vals, ks.value)):
                out.append(f"trace line {ln!r} differs from key step {ks.type} {ks.phrase!r} {ks.value}")
    # key-step ground truth
    by_phrase = {}
    for n in w.graph.nodes:
        for p in n.phrases:
            by_phrase.setdefault(p, n.object_id)
    marks = {f"the object marked ({m['label']})": m["object_id"] for m in (qa.answer_struct or {}).get("marks") or []}
    for ks in qa.key_steps:
        oid = marks.get(ks.phrase, by_phrase.get(ks.phrase))
        if ks.type == "Position":
            if ks.phrase.startswith("the free space"):
                pts = (qa.answer_struct or {}).get("points") or [[None, None]]
                if any(abs(a - b) > KEY_TOL for a, b in zip(ks.value, pts[0])):
                    out.append(f"key step {ks.phrase!r} {ks.value} is not the free-space answer {pts[0]}")
                continue
            if oid is None:
                oid = (qa.targets or [None])[-1] if ks is qa.key_steps[-1] else None
            if oid is None:
                out.append(f"key step phrase {ks.phrase!r} names no object")
                continue
            x, y = denormalise_point(ks.value[0], ks.value[1], w.frame.camera.width, w.frame.camera.height)
            if not w.mask(oid)[y, x]:
                out.append(f"key step {ks.phrase!r} point {ks.value} is outside object {oid}'s mask")
        elif oid is None:
            out.append(f"key step phrase {ks.phrase!r} names no object")
        elif ks.type == "Size":
            ref = _size(w.objects[oid].box)
            if any(abs(a - b) > KEY_TOL for a, b in zip(ks.value, ref)):
                out.append(f"key step Size {ks.phrase!r} {ks.value} differs from the box {[round(r, 3) for r in ref]}")
        elif ks.type == "Orientation":
            o = w.objects[oid]
            if o.front is None:
                out.append(f"key step Orientation {ks.phrase!r}: object {oid} has no front")
                continue
            v = w.frame.camera.world_from_cam[:3, :3].T @ o.front_world
            v = v / np.linalg.norm(v)
            if any(abs(a - b) > KEY_TOL for a, b in zip(ks.value, v)):
                out.append(f"key step Orientation {ks.phrase!r} {ks.value} differs from {np.round(v, 3).tolist()}")
    return out


def verify_sample(sample: Sample) -> list[dict]:
    """Failures of one sample's QA pairs: [{"sample_id", "qa_id", "template", "reason"}]; [] = all pass."""
    frames = {f.frame_id: f for f in sample.frames}
    graphs = {g.frame_id: g for g in sample.graphs}
    order = [f.frame_id for f in sample.frames]
    worlds: dict[str, _World] = {}
    out = []
    for qa in sample.qa:
        for reason in verify_qa(qa, frames, graphs, worlds, order):
            out.append({"sample_id": sample.sample_id, "qa_id": qa.qa_id, "template": qa.template, "reason": reason})
    return out


def verify_samples(samples) -> dict:
    """Summary over samples: {"qa_pairs", "passed", "failed", "failures"}."""
    total = failed = 0
    failures: list[dict] = []
    for s in samples:
        f = verify_sample(s)
        bad = {x["qa_id"] for x in f}
        total += len(s.qa)
        failed += len(bad)
        failures += f
    return {"qa_pairs": total, "passed": total - failed, "failed": failed, "failures": failures}
