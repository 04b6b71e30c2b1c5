"""Independent re-check of `point_depth` QA pairs (called from qa/verify.py).

Why separate code: it shares nothing with qa/pointdepth.py. It parses the points back out of the
question text, denormalises them to pixels, re-reads the stored depth map, and recomputes the depth,
the closer/farther ordering and the camera rotation from the intrinsics and pose alone.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import Frame, QAPair
from refspatial_gen.qa.verify_units import stated_length

DEPTH_TOL = 0.01  # m: stated depth vs the depth map
ANGLE_TOL = math.radians(1.0)
# a queried depth must be locally consistent (the generator's rule, re-checked here with its own code):
# half-window at 640 px width, share of valid pixels, and p90-p10 spread relative to the depth; the wider
# window on approximate (splatted or estimated) depth
_WIN = {False: (4, 0.9), True: (12, 0.95)}
_SPREAD = 0.03
_POINT = re.compile(r"\[\((\d\.\d{3}), (\d\.\d{3})\)\]")
_NUM = re.compile(r"(\d+(?:\.\d+)?) (centimeters?|meters|degrees)")


def _pixel(frame: Frame, p: Any) -> tuple[int, int]:
    return denormalise_point(float(p[0]), float(p[1]), frame.camera.width, frame.camera.height)


def _depth(frame: Frame, p: Any) -> float:
    u, v = _pixel(frame, p)
    z = float(frame.depth[v, u])
    if not (math.isfinite(z) and z > 0):
        raise ValueError(f"no valid depth at pixel ({u}, {v})")
    return z


def _approximate(frame: Frame) -> bool:
    meta = frame.meta
    dep = meta.get("depth")
    origin = dep.get("origin", "") if isinstance(dep, dict) else ""
    if meta.get("depth_source") == "splatted_points":
        return True
    return frame.source == "image" and not str(origin).startswith("provided")


def _inconsistent(frame: Frame, p: Any) -> str | None:
    """Why the depth around the point does not support a depth question (None when it does)."""
    u, v = _pixel(frame, p)
    half, share = _WIN[_approximate(frame)]
    k = max(1, int(round(half * frame.camera.width / 640)))
    h, w = frame.depth.shape[:2]
    patch = np.asarray(frame.depth, np.float64)[max(v - k, 0) : min(v + k + 1, h), max(u - k, 0) : min(u + k + 1, w)]
    vals = patch[np.isfinite(patch) & (patch > 0)]
    if vals.size < share * patch.size:
        return f"only {vals.size}/{patch.size} valid depths around ({u}, {v})"
    spread = float(np.quantile(vals, 0.9) - np.quantile(vals, 0.1))
    z = float(frame.depth[v, u])
    if spread > _SPREAD * z:
        return f"depth around ({u}, {v}) spreads {spread:.3f} m (> {_SPREAD:.0%} of {z:.3f} m)"
    return None


def _stated(answer: str) -> float | None:
    m = _NUM.search(answer)
    if m is None:
        return None
    x = float(m.group(1))
    unit = m.group(2)
    if unit.startswith("centimeter"):
        return x / 100.0
    if unit == "degrees":
        return math.radians(x)
    return x


def _turn(frame: Frame, p: Any, axis: str) -> float:
    """Camera rotation to face the ray through the point: atan2(x, z); vertical in the gravity-levelled frame."""
    cam = frame.camera
    u, v = _pixel(frame, p)
    K_inv = np.linalg.inv(cam.K)
    ray = K_inv @ np.array([u + 0.5, v + 0.5, 1.0])
    if axis == "horizontal":
        return math.atan2(ray[0], ray[2])
    if not cam.gravity_known:
        raise ValueError("vertical rotation asked on a frame without gravity")
    world_ray = cam.cam_to_world(ray[None]) - cam.position
    world_ray = world_ray[0]
    look = cam.cam_to_world(np.array([[0.0, 0.0, 1.0]]))[0] - cam.position
    horiz = np.array([look[0], look[1]])
    horiz /= np.linalg.norm(horiz)
    return math.atan2(world_ray[2], world_ray[0] * horiz[0] + world_ray[1] * horiz[1])


def verify_point_depth(qa: QAPair, frame: Frame) -> list[str]:
    """Reasons a point_depth QA pair fails (empty when it passes)."""
    s = qa.answer_struct
    pts = [(float(a), float(b)) for a, b in _POINT.findall(qa.question)]
    stored = [tuple(float(x) for x in p) for p in s.get("query_points") or []]
    if not pts or pts != stored:
        return [f"question points {pts} differ from the stored query points {stored}"]
    if frame.depth is None:
        return ["frame has no depth map"]
    out: list[str] = []
    try:
        q = s.get("quantity")
        if q == "depth" or s.get("kind") == "choice":
            out += [w for w in (_inconsistent(frame, p) for p in pts) if w is not None]
        if s.get("kind") == "number" and q == "depth":
            z = _depth(frame, pts[0])
            if abs(float(s["value"]) - z) > DEPTH_TOL:
                out.append(f"depth {s['value']:.3f} m but the depth map reads {z:.3f} m")
            said = stated_length(qa.answer)  # any length unit, at its precision
            if isinstance(said, str) or abs(said[0] - z) > DEPTH_TOL + said[1]:
                out.append(f"answer text {qa.answer!r} does not match the depth {z:.3f} m")
        elif s.get("kind") == "number" and q in ("rotation_horizontal", "rotation_vertical"):
            axis = q.split("_")[1]
            a = _turn(frame, pts[0], axis)
            if abs(float(s["value"]) - a) > ANGLE_TOL:
                out.append(f"{q} {math.degrees(float(s['value'])):.1f} deg but recomputed {math.degrees(a):.1f} deg")
            t = _stated(qa.answer)
            words = ("right", "left") if axis == "horizontal" else ("up", "down")
            want = words[0] if a > 0 else words[1]
            if t is None or abs(t - abs(a)) > ANGLE_TOL or f"rotate {want} " not in qa.answer:
                out.append(f"answer text {qa.answer!r} does not say rotate {want} {math.degrees(abs(a)):.1f} degrees")
        elif s.get("kind") == "choice":
            if len(pts) != 2:
                return [f"choice needs two points, got {len(pts)}"]
            za, zb = _depth(frame, pts[0]), _depth(frame, pts[1])
            margin = max(0.05, 0.03 * max(za, zb))
            if abs(za - zb) <= margin:
                out.append(f"depths {za:.3f} and {zb:.3f} m differ by less than the margin {margin:.3f} m")
            rel = s.get("relation")
            if rel not in ("front", "behind") or rel not in qa.relations:
                out.append(f"choice relation {rel!r} is not front/behind or not listed in relations")
            want = "AB"[int(za > zb)] if rel == "front" else "AB"[int(za < zb)]
            m = re.match(r"^\(([AB])\)", qa.answer)
            if s.get("letter") != want or m is None or m.group(1) != want:
                out.append(
                    f"answer {qa.answer!r} (letter {s.get('letter')}) but depths {za:.3f}, {zb:.3f} m "
                    f"give ({want}) for {rel}"
                )
            word = "closer" if rel == "front" else "farther"
            if word not in qa.question and ("nearer" if rel == "front" else "farther") not in qa.question:
                out.append(f"question does not ask which point is {word}")
        else:
            out.append(f"unknown point_depth answer kind {s.get('kind')!r} / quantity {q!r}")
    except (ValueError, KeyError, IndexError, TypeError) as e:
        out.append(f"point_depth record does not re-check: {type(e).__name__}: {e}")
    if qa.steps != 1:
        out.append(f"point_depth questions are 1 step, record says {qa.steps}")
    return out
