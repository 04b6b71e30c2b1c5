"""One work unit through every stage: source -> frames -> scene graphs -> QA pairs -> Sample."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.core.model import Sample
from refspatial_gen.core.serialize import as_stored
from refspatial_gen.graph.visibility import floor_of
from refspatial_gen.recipe import Recipe
from refspatial_gen.run.plan import Unit, unit_rng
from refspatial_gen.sources import get_source
from refspatial_gen.truth.lookalikes import add_lookalike_stand_ins


@dataclass
class StageTimer:
    seconds: dict[str, float] = field(default_factory=lambda: {"load": 0.0, "graph": 0.0, "qa": 0.0, "write": 0.0})

    def add(self, stage: str, t0: float) -> float:
        t = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + (t - t0)
        return t


def make_sample(recipe: Recipe, unit: Unit, timer: StageTimer, out_dir: str | None = None) -> Sample:
    """Build the unit's sample. Raises DropUnit (with a reason) when the unit yields nothing usable."""
    from refspatial_gen.graph import build_graph
    from refspatial_gen.qa import generate_qa

    spec = recipe.sources[[s.index for s in recipe.sources].index(unit.source_index)]
    rng = unit_rng(recipe.seed, unit.uid)
    t = time.perf_counter()
    try:
        frames = get_source(unit.kind).load(unit.key, rng, spec.config)
    except OSError as e:  # a file the unit needs cannot be read (permissions, a folder where a file should be, EIO)
        raise DropUnit("input_unreadable", f"{e.filename or unit.key}: {e.strerror or e}") from e
    except InputError as e:  # the input changed since planning
        raise DropUnit("input_invalid", str(e)) from e
    if not frames:
        raise DropUnit("no_frames", unit.key)
    for f in frames:
        try:
            f.validate()
        except ValueError as e:
            raise DropUnit("invalid_frame", f"{f.frame_id}: {e}") from e
    if floor_of(recipe.graph).lookalike_stand_ins:  # look-alikes count where a category is named
        frames = [add_lookalike_stand_ins(f) for f in frames]
    frames = [as_stored(f) for f in frames]  # graphs and QA on the numbers the shard keeps (verify reads them)
    t = timer.add("load", t)
    graphs = [build_graph(f, recipe.graph) for f in frames]
    t = timer.add("graph", t)
    truth: dict[str, int] = {}  # QA pairs the truth checks withheld, by reason (qa/faint.py)
    qa = generate_qa(frames, graphs, rng, recipe.qa, truth=truth)
    timer.add("qa", t)
    if not qa:
        raise DropUnit("no_questions", f"{unit.key}: no question passed the checks")
    sample = Sample(
        sample_id=unit.uid,
        frames=frames,
        graphs=graphs,
        qa=qa,
        unit_key=unit.key,
        meta={"source": unit.kind, **({"truth": dict(sorted(truth.items()))} if truth else {})},
    )
    if recipe.rewrite is not None:  # LLM rewording of the questions, each checked (docs/rewrite.md)
        from refspatial_gen.rewrite.stage import rewrite_sample

        t = time.perf_counter()
        rewrite_sample(recipe.rewrite, sample, out_dir)
        timer.add("rewrite", t)
    return sample
