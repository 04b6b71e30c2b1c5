"""Nothing proportional to the number of samples stays alive in a worker (regression: a leaking QA index cache)."""

import gc
import weakref

import numpy as np

from refspatial_gen.graph import build_graph
from refspatial_gen.qa.generate import generate_qa
from refspatial_gen.recipe import load_recipe
from refspatial_gen.sources.toy import toy_frame
from tests.helpers.runs import write_toy_recipe


def test_graphs_and_frames_are_freed_after_their_sample(tmp_path):
    recipe = load_recipe(write_toy_recipe(tmp_path))
    refs = []
    for i in range(20):
        f = toy_frame(np.random.default_rng(i), 5, 160, 120, frame_id=f"toy:{i}")
        g = build_graph(f, recipe.graph)
        generate_qa([f], [g], np.random.default_rng(i), recipe.qa)
        refs.append((weakref.ref(f), weakref.ref(g)))
        del f, g
    gc.collect()
    alive = sum(1 for rf, rg in refs if rf() is not None or rg() is not None)
    assert alive == 0, f"{alive} of 20 samples still referenced (generate_qa keeps no index past its call)"


def test_generation_leaves_no_reference_cycles(tmp_path):
    """A returned Reject kept its traceback, whose frames held the scene index in a cycle that only the garbage
    collector could free (it cost about 10% of QA time in collector passes). Generation must leave no cycles."""
    recipe = load_recipe(write_toy_recipe(tmp_path))
    f = toy_frame(np.random.default_rng(0), 6, 160, 120, frame_id="toy:0")
    g = build_graph(f, recipe.graph)
    generate_qa([f], [g], np.random.default_rng(0), recipe.qa)  # warm module-level caches first
    gc.collect()
    gc.disable()
    try:
        for i in range(5):
            qa = generate_qa([f], [g], np.random.default_rng(i), recipe.qa)
            assert qa
        del qa
        found = gc.collect()
    finally:
        gc.enable()
    assert found == 0, f"{found} objects were only reachable through reference cycles"
