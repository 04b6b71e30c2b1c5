"""`sim usd` and `sim gallery` show exactly the scenes a run of the recipe writes (same config, same unit
seeding "s<source index>/<unit key>"). Before this was fixed the CLI seeded from the bare unit key."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from refspatial_gen.core.serialize import as_stored

os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]


def _run_frames(unit_index: int):
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.pipeline import StageTimer, make_sample
    from refspatial_gen.run.plan import plan_units

    recipe = load_recipe(ROOT / "recipes" / "default.yaml", scenes=unit_index + 1)
    unit = plan_units(recipe)[unit_index]
    return unit.key, make_sample(recipe, unit, StageTimer()).frames


def _centres(frame) -> list:
    """The scene's own objects (a run adds look-alike stand-ins, truth/lookalikes.py, which the CLI's scene
    views do not need: they copy real objects' boxes)."""
    from refspatial_gen.truth.lookalikes import is_stand_in

    return [o.box.center.tolist() for o in frame.objects if not is_stand_in(o)]


def _same(a, b) -> None:
    assert [f.frame_id for f in a] == [f.frame_id for f in b]
    for fa, fb in zip(a, b):
        assert np.array_equal(fa.rgb, fb.rgb) and np.array_equal(fa.depth, fb.depth)
        assert _centres(fa) == _centres(fb)


def test_sim_usd_and_gallery_give_the_run_scene(tmp_path: Path, monkeypatch) -> None:
    import refspatial_gen.sources.sim as sim
    import refspatial_gen.sources.sim.usd as usd
    from refspatial_gen.cli import main

    key, frames = _run_frames(1)
    seen: dict[str, list] = {}
    real = sim.generate

    def spy(unit_key, rng, cfg, **kw):
        out = real(unit_key, rng, cfg, **kw)
        seen[unit_key] = out[0] if kw.get("keep_scene") else out
        return out

    monkeypatch.setattr(sim, "generate", spy)
    monkeypatch.setattr(usd, "export_usd", lambda *a, **k: str(tmp_path / "scene.usda"))
    assert main(["sim", "usd", "--unit", key, "--out", str(tmp_path / "scene.usda")]) == 0
    _same([as_stored(f) for f in seen.pop(key)], frames)  # a run builds on the frames as stored
    assert main(["sim", "gallery", "--scenes", "2", "--out", str(tmp_path / "sheet.png")]) == 0
    _same([as_stored(f) for f in seen[key]], frames)
    assert (tmp_path / "sheet.png").stat().st_size > 0
