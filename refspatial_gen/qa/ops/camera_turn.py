"""camera_turn: multi-view: which way the camera turned from the first image to the second (1 step)."""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import TYPE_CHECKING, Any

import numpy as np

from refspatial_gen.qa.index import Reject
from refspatial_gen.qa.ops.base import OPTION, TURN_AXES, Arg, Op, Recorded
from refspatial_gen.qa.program import Step
from refspatial_gen.qa.values import OptionValue

if TYPE_CHECKING:
    from refspatial_gen.qa.index import SceneIndex
    from refspatial_gen.qa.values import Context
    from refspatial_gen.qa.verify_world import Run

TURN_MARGIN = math.radians(5.0)  # a camera turn smaller than this between two views is not asked about
VERIFY_MARGIN = math.radians(2.0)  # verify: a stored turn smaller than this cannot be told


def camera_turn(first: SceneIndex, second: SceneIndex, axis: str) -> float:
    """Signed turn of the camera from the first view to the second, radians: + = left (horizontal) / up
    (vertical), from the optical axes in the gravity-aligned world frame (z up)."""
    f1 = first.frame.camera.world_from_cam[:3, 2]
    f2 = second.frame.camera.world_from_cam[:3, 2]
    if axis == "horizontal":
        d = math.atan2(f2[1], f2[0]) - math.atan2(f1[1], f1[0])
        return (d + math.pi) % (2 * math.pi) - math.pi
    e1 = math.asin(max(-1.0, min(1.0, f1[2] / np.linalg.norm(f1))))
    e2 = math.asin(max(-1.0, min(1.0, f2[2] / np.linalg.norm(f2))))
    return e2 - e1


class CameraTurn(Op):
    name = "camera_turn"
    args = {"axis": Arg("axis", True, tuple(TURN_AXES))}
    out = OPTION
    doc = "multi-view: which way the camera turned from the first image to the second (1 step)"

    def weight(self, present: Collection[str]) -> int:
        return 1

    def needs(self, st: Step) -> dict[str, Any]:
        return {"multiview": True}

    def recorded(self, st: Step) -> Recorded:
        return Recorded(relations=("rotation_" + st.args["axis"].value,))

    def run(self, st: Step, env: dict[str, Any], prev: Any, ctx: Context) -> Any:
        if ctx.second is None:
            raise Reject("single_view")
        axis = st.args["axis"].value
        d = camera_turn(ctx.idx, ctx.second, axis)
        if abs(d) < TURN_MARGIN:
            raise Reject("margin")
        return OptionValue(TURN_AXES[axis], 0 if d > 0 else 1)

    def verify(self, run: Run, a: dict[str, Any], prev: Any, st: dict[str, Any]) -> Any:
        """Recomputed from the two stored cameras' optical axes (not the generator's index)."""
        fids = run.qa.frame_ids
        if len(fids) != 2:
            raise run.fail("camera_turn needs two frames")
        a1 = run.frames[fids[0]].camera.world_from_cam[:3, 2]
        a2 = run.frames[fids[1]].camera.world_from_cam[:3, 2]
        if a["axis"] == "horizontal":
            d = math.atan2(a2[1], a2[0]) - math.atan2(a1[1], a1[0])
            d = (d + math.pi) % (2 * math.pi) - math.pi
        else:
            d = math.asin(a2[2] / np.linalg.norm(a2)) - math.asin(a1[2] / np.linalg.norm(a1))
        words = ("left", "right") if a["axis"] == "horizontal" else ("up", "down")
        if abs(d) < VERIFY_MARGIN:
            raise run.undecided(f"camera turn {math.degrees(d):.2f} degrees is too small to tell")
        return ("option", words[0] if d > 0 else words[1])


OP = CameraTurn()
