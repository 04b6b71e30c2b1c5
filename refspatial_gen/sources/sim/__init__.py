"""Simulated source: MuJoCo tabletop and room scenes with exact ground truth (see docs/sim.md)."""

from refspatial_gen.sources.sim.source import CONFIG_FIELDS, SimSource, generate

__all__ = ["CONFIG_FIELDS", "SimSource", "generate"]
