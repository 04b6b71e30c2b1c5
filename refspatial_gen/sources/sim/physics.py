"""Physics until everything is at rest (the model itself is built in model.py).

Why a velocity criterion: a fixed step count either wastes time on quiet scenes or stops a rolling
object mid-motion; we step in chunks until every free body is slower than a threshold for several
consecutive checks, and drop the scene (`physics_not_settled`) when the step cap is reached.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.sources.sim.model import HIDDEN_GROUP, SimModel, build_model

__all__ = ["HIDDEN_GROUP", "SimModel", "build_model", "settle", "body_pose"]


def settle(sim: SimModel, cfg: dict[str, Any]) -> dict[str, float]:
    """Step until all free bodies are at rest; raise DropUnit when they are not after the step cap."""
    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    lin_tol, ang_tol = float(cfg.get("settle_lin_vel", 0.005)), float(cfg.get("settle_ang_vel", 0.05))
    cap, chunk, need = int(cfg.get("settle_max_steps", 3000)), 25, 3
    steps, quiet = 0, 0
    lin = ang = 0.0
    while steps < cap:
        for _ in range(chunk):
            mujoco.mj_step(m, d)
        steps += chunk
        if m.nv == 0:
            break
        v = d.qvel.reshape(-1, 6)
        lin, ang = float(np.abs(v[:, :3]).max()), float(np.abs(v[:, 3:]).max())
        if not np.all(np.isfinite(d.qvel)):
            raise DropUnit("physics_unstable", "non-finite velocities")
        quiet = quiet + 1 if (lin < lin_tol and ang < ang_tol) else 0
        if quiet >= need and steps >= 100:
            break
    else:
        raise DropUnit("physics_not_settled", f"max speed {lin:.3f} m/s, {ang:.3f} rad/s after {steps} steps")
    if d.ncon:
        pen = -float(d.contact.dist[: d.ncon].min())
        if pen > float(cfg.get("max_penetration", 0.006)):
            raise DropUnit("interpenetration", f"contact penetration {pen * 1000:.1f} mm after settling")
    return {"steps": steps, "sim_time": steps * m.opt.timestep, "max_lin_vel": lin, "max_ang_vel": ang}


def body_pose(sim: SimModel, k: int) -> tuple[np.ndarray, np.ndarray]:
    """World position and rotation matrix of object k's body frame (origin = bottom centre at placement)."""
    bid = sim.body_ids[k]
    return sim.data.xpos[bid].copy(), sim.data.xmat[bid].reshape(3, 3).copy()
