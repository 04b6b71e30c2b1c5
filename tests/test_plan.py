import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from refspatial_gen.run.plan import Unit, plan_groups, split_by_weight, unit_rng


@given(st.integers(0, 10_000), st.lists(st.floats(0.01, 10), min_size=1, max_size=6))
def test_split_by_weight_sums_exactly(total, weights):
    parts = split_by_weight(total, weights)
    assert sum(parts) == total and all(p >= 0 for p in parts)
    exact = np.array(weights) / sum(weights) * total
    assert np.all(np.abs(np.array(parts) - exact) < 1.0 + 1e-9)


def test_unit_rng_depends_only_on_seed_and_uid():
    a = unit_rng(5, "s0/sim:000001").random(4)
    assert np.array_equal(a, unit_rng(5, "s0/sim:000001").random(4))
    assert not np.array_equal(a, unit_rng(6, "s0/sim:000001").random(4))
    assert not np.array_equal(a, unit_rng(5, "s0/sim:000002").random(4))


def test_groups_are_fixed_by_position():
    units = [Unit(f"s0/toy:{i:06d}", 0, "toy", f"toy:{i:06d}") for i in range(10)]
    groups = plan_groups(units, 4)
    assert [len(g.units) for g in groups] == [4, 4, 2]
    assert [g.name for g in groups] == ["shard-00000", "shard-00001", "shard-00002"]
