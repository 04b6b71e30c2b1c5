"""Independent re-check of stored QA pairs (`refspatial-gen verify DIR`, `verify_sample`).

Why a second code path: a check that shares the generator's code shares its bugs. The verifier reads only
what a shard stores and re-derives every answer on its own: relations re-evaluated on the frame's geometry
through the relation registry's `evaluate` (not the stored facts or the generator's index), phrases by the
graph's independent resolver, points against decoded masks, free points against the surface and depth
map, numbers from the stored 3D boxes; visibility and size truth in verify_truth.py.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from typing import Any

import numpy as np

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import Frame, FreeSpaceRegion, QAPair, Sample, SceneGraph
from refspatial_gen.qa.ops import OPS
from refspatial_gen.qa.verify_corners import check_corners
from refspatial_gen.qa.verify_lookalike import check_lookalikes
from refspatial_gen.qa.verify_nesting import check_nesting
from refspatial_gen.qa.verify_nesting import walk as _walk
from refspatial_gen.qa.verify_photo import check_photo
from refspatial_gen.qa.verify_recess import check_recess
from refspatial_gen.qa.verify_truth import check_truth
from refspatial_gen.qa.verify_units import LENGTHS, check_length_text, check_size_step
from refspatial_gen.qa.verify_world import ANGLE_TOL, LENGTH_ABS_TOL, LENGTH_REL_TOL, Fail, Run, Undecided, World, _size

LETTERS = "ABCDEFGH"
KEY_TOL = 1.5e-3  # key-step values are rounded to 3 decimals


def _steps_of(program: list[dict[str, Any]]) -> int:
    """The step count the record's own program gives (each op's formats.md rule over the stored arguments)."""
    n = 0
    for st in program:
        op, a = st.get("op"), st.get("args") or {}
        if isinstance(op, str) and op in OPS:
            n += OPS[op].weight({k for k, v in a.items() if v is not None})
    return max(1, n)


def _close(a: float, b: float, q: str) -> bool:
    if q in ("angle", "rotation_horizontal", "rotation_vertical"):
        return abs(a - b) <= ANGLE_TOL
    return abs(a - b) <= max(LENGTH_ABS_TOL, LENGTH_REL_TOL * max(abs(a), abs(b)))


# ------------------------------------------------------------------------------------------ checks
_POINTS = re.compile(r"\(\s*(-?[0-9.]+)\s*,\s*(-?[0-9.]+)\s*\)")
_TRACE_LINE = re.compile(r"^\[(Position|Orientation|Size)\] \[(.+)\]: (?:\(([^)]*)\)|(-?[0-9.]+) m)$")


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


def verify_qa(
    qa: QAPair,
    frames: dict[str, Frame],
    graphs: dict[str, SceneGraph],
    worlds: dict[str, World],
    order: list[str] | None = None,
) -> list[str]:
    """Reasons this QA pair fails (empty when it passes). `order`: the sample's frame ids in stored order
    (drawn marks name their image by position in it)."""
    problems: list[str] = []
    if not qa.frame_ids or any(f not in frames or f not in graphs for f in qa.frame_ids):
        return [f"frame ids {qa.frame_ids} not in the sample"]
    fid = qa.frame_ids[0]
    frame, graph = frames[fid], graphs[fid]
    if fid not in worlds:
        worlds[fid] = World(frame, graph)
    w = worlds[fid]
    if tuple(qa.image_size) != (frame.camera.width, frame.camera.height):
        problems.append(
            f"image_size {list(qa.image_size)} is not the frame's {[frame.camera.width, frame.camera.height]}"
        )
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
    run = Run(w, frames, qa)
    final = None
    try:
        final, env = run.run()
    except Undecided as e:
        problems.append(f"relation asked inside its margin: {e}")
    except Fail as e:
        problems.append(f"program does not re-evaluate: {e}")
    except (KeyError, TypeError, ValueError, IndexError) as e:
        problems.append(f"program record unreadable: {type(e).__name__}: {e}")
    if final is not None:
        for k, st in enumerate(qa.program):
            if st["op"] not in OPS or not OPS[st["op"]].droppable:
                continue
            try:
                alt, _ = run.run(drop=k)
            except (Undecided, Fail):
                continue
            if _answer_key(alt) == _answer_key(final):
                problems.append(f"degenerate step {k + 1} ({st['op']}): removing it leaves the answer unchanged")
        for k, st in enumerate(qa.program):
            stored, got = st.get("out"), env.get(st["as"])
            if isinstance(got, frozenset) and isinstance(stored, list) and sorted(got) != sorted(stored):
                problems.append(f"step {k + 1} ({st['op']}) stored {sorted(stored)} but re-evaluates to {sorted(got)}")
        problems += _check_answer(qa, final, w, frame, graph)
    problems += _check_marks(qa, w, order if order is not None else list(frames))
    problems += check_lookalikes(qa, frames, graphs)  # look-alike stand-ins stored (truth/lookalikes.py)
    problems += check_truth(qa, frames, graphs)  # visibility floor, phrases without faint objects, metric trust
    problems += check_photo(qa, frame)  # photo rules: unseen feet, same-category sizes, incomplete categories
    problems += check_corners(qa, frame, graph)  # corners/edges seen, at the top face's extent
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
                    out.append(
                        f"phrase {v['phrase']!r} resolves to {list(ids)}, not to object {v['object']} "
                        "(not a unique reference)"
                    )
                if v["phrase"].lower() not in q:
                    out.append(f"phrase {v['phrase']!r} does not appear in the question")
    out += check_nesting(qa)
    return out


def _check_answer(qa: QAPair, final: Any, w: World, frame: Frame, graph: SceneGraph) -> list[str]:
    s = qa.answer_struct or {}
    kind = s.get("kind")
    if kind in ("points", "region"):
        return _check_point(qa, s, final, w, frame, graph)
    if kind == "choice":
        return _check_choice(qa, s, final)
    if kind == "number":
        return _check_number(qa, s, final)
    return [f"unknown answer kind {kind!r}"]


def _check_point(qa: QAPair, s: dict[str, Any], final: Any, w: World, frame: Frame, graph: SceneGraph) -> list[str]:
    W, H = frame.camera.width, frame.camera.height
    out: list[str] = []
    pts = s.get("points") or []
    text_pts = [(float(x), float(y)) for x, y in _POINTS.findall(qa.answer)]
    if len(pts) != 1 or len(text_pts) != 1:
        return [f"expected one answer point, got {pts} / {qa.answer!r}"]
    p = (float(pts[0][0]), float(pts[0][1]))
    if abs(p[0] - text_pts[0][0]) > 1e-9 or abs(p[1] - text_pts[0][1]) > 1e-9:
        out.append(f"answer text {qa.answer!r} differs from the structured point {p}")
    if not (0.0 <= p[0] <= 1.0 and 0.0 <= p[1] <= 1.0):
        out.append(f"answer point {p} outside [0, 1]")
    if s.get("kind") == "points":
        if not (isinstance(final, tuple) and final[0] == "object"):
            return out + [f"program gives {final!r}, not an object"]
        oid = final[1]
        if list(s.get("object_ids") or []) != [oid] or list(qa.targets) != [oid]:
            out.append(f"answer names object {s.get('object_ids')} / targets {qa.targets}, the program gives {oid}")
        x, y = denormalise_point(p[0], p[1], W, H)
        if not w.mask(oid)[y, x]:
            out.append(f"answer point {p} (pixel {x},{y}) is outside the visible mask of object {oid}")
        if frame.source == "scan":
            out += check_recess(frame, oid, x, y)
    else:
        from refspatial_gen.graph.freespace import check_free_point

        reg = _find_region(graph, s.get("region") or {})
        if reg is None:
            out.append(f"free-space region {s.get('region')} is not in the scene graph")
        else:
            out += [f"free point {p}: {m}" for m in check_free_point(frame, graph, reg, p)]
    return out


def _check_choice(qa: QAPair, s: dict[str, Any], final: Any) -> list[str]:
    out: list[str] = []
    letter = s.get("letter")
    opts = list(s.get("options") or [])
    m = re.match(r"^\(([A-H])\)(?: (.*))?$", qa.answer)
    if not m or m.group(1) != letter or letter not in LETTERS[: max(1, len(opts))]:
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


def _check_number(qa: QAPair, s: dict[str, Any], final: Any) -> list[str]:
    out: list[str] = []
    if not (isinstance(final, tuple) and final[0] == "number"):
        return [f"number answer but the program gives {final!r}"]
    q, got = final[1], final[2]
    v = float(s.get("value", float("nan")))
    if not _close(v, got, q):
        out.append(f"{q}: answer {v:.4f} but the geometry gives {got:.4f}")
    if q in LENGTHS:  # a length in any unit people use, at its unit's precision
        return out + check_length_text(qa.answer, v)
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
        tol = (
            0.006
            if "meter" in qa.answer and "centi" not in qa.answer
            else (0.0051 if "centi" in qa.answer else math.radians(0.051))
        )
        ref = abs(v) if q == "angle" else v
        if abs(t - ref) > tol:
            out.append(f"answer text {qa.answer!r} does not render the value {v:.4f}")
    return out


def _check_marks(qa: QAPair, w: World, order: list[str]) -> list[str]:
    """Drawn marks belong on the asked image: each names the position of the QA's frame in the sample, an
    object of that frame, its 2D box as stored, and (when given) a point inside that object's visible mask."""
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
        if box is not None and (
            o.bbox2d is None or any(abs(float(a) - float(b)) > 0.051 for a, b in zip(box, o.bbox2d))
        ):
            out.append(f"mark ({label}) box {box} is not object {oid}'s 2D box")
        pt = m.get("point")
        if pt is not None:
            x, y = denormalise_point(float(pt[0]), float(pt[1]), W, H)
            if not w.mask(oid)[y, x]:
                out.append(f"mark ({label}) point {pt} is outside object {oid}'s visible mask")
    return out


def _find_region(graph: SceneGraph, r: dict[str, Any]) -> FreeSpaceRegion | None:
    for reg in graph.free_space:
        if (
            reg.surface_id == r.get("surface_id")
            and reg.kind == r.get("kind")
            and list(reg.anchors) == list(r.get("anchors") or [])
            and reg.label == r.get("label", reg.label)
        ):
            return reg
    return None


def _check_trace(qa: QAPair, w: World) -> list[str]:
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
            vals = [float(x) for x in (mm.group(3) if mm.group(3) is not None else mm.group(4)).split(",")]
            if (
                mm.group(1) != ks.type
                or mm.group(2) != ks.phrase
                or len(vals) != len(ks.value)
                or any(abs(a - b) > 1e-9 for a, b in zip(vals, ks.value))
            ):
                out.append(f"trace line {ln!r} differs from key step {ks.type} {ks.phrase!r} {ks.value}")
    # key-step ground truth
    by_phrase: dict[str, int] = {}
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
                oid = qa.targets[-1] if qa.targets and ks is qa.key_steps[-1] else None
            if oid is None:
                out.append(f"key step phrase {ks.phrase!r} names no object")
                continue
            x, y = denormalise_point(ks.value[0], ks.value[1], w.frame.camera.width, w.frame.camera.height)
            if not w.mask(oid)[y, x]:
                out.append(f"key step {ks.phrase!r} point {ks.value} is outside object {oid}'s mask")
        elif oid is None:
            out.append(f"key step phrase {ks.phrase!r} names no object")
        elif ks.type == "Size":
            box = w.objects[oid].box
            out += check_size_step(ks, _size(box), float(np.prod(box.size)))
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


def verify_sample(sample: Sample) -> list[dict[str, Any]]:
    """Failures of one sample's QA pairs: [{"sample_id", "qa_id", "template", "reason"}]; [] = all pass."""
    frames = {f.frame_id: f for f in sample.frames}
    graphs = {g.frame_id: g for g in sample.graphs}
    order = [f.frame_id for f in sample.frames]
    worlds: dict[str, World] = {}
    out = []
    for qa in sample.qa:
        for reason in verify_qa(qa, frames, graphs, worlds, order):
            out.append({"sample_id": sample.sample_id, "qa_id": qa.qa_id, "template": qa.template, "reason": reason})
    return out


def verify_samples(samples: Iterable[Sample]) -> dict[str, Any]:
    """Summary over samples: {"qa_pairs", "passed", "failed", "failures"}."""
    total = failed = 0
    failures: list[dict[str, Any]] = []
    for s in samples:
        f = verify_sample(s)
        bad = {x["qa_id"] for x in f}
        total += len(s.qa)
        failed += len(bad)
        failures += f
    return {"qa_pairs": total, "passed": total - failed, "failed": failed, "failures": failures}
