"""Simulated source: MuJoCo tabletop and room scenes with exact ground truth (see docs/sim.md)."""

import os

# Headless rendering: EGL unless the user chose another backend (must be set before mujoco's GL import).
os.environ.setdefault("MUJOCO_GL", "egl")
if os.environ["MUJOCO_GL"] == "egl":
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from refspatial_gen.sources.sim.source import CONFIG_FIELDS, SimSource, generate  # noqa: E402

__all__ = ["CONFIG_FIELDS", "SimSource", "generate"]
