"""The stream as a well-behaved torch IterableDataset (#22 defect 3): picklable, every DataLoader start
method, persistent workers with set_epoch, per-rank len, rank-checked checkpoints, elastic resume,
record() with the default collate, skip-and-count of damaged shards, and a 2-process torchrun."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.stream_items import ids_of, item_id
from refspatial_gen.shards import ShardWriter, write_index
from refspatial_gen.sources.toy_samples import make_samples
from refspatial_gen.shards.trust import forget
from refspatial_gen.stream import ShardStream

torch = pytest.importorskip("torch")
from torch.utils.data import DataLoader  # noqa: E402

SIZES = [4, 2, 5, 3, 6, 4]
N = sum(SIZES)


@pytest.fixture(scope="module")
def shard_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("torchstream")
    samples = make_samples(N, seed=13, width=48, height=32, n_qa=2)
    infos, k = [], 0
    for i, n in enumerate(SIZES):
        w = ShardWriter(d / f"shard-{i:05d}.mcap", image_format="png")
        for s in samples[k:k + n]:
            w.write(s)
        k += n
        infos += w.finish()
    write_index(d, [x.to_dict() for x in infos], {"seed": 0})
    return d, sorted(s.sample_id for s in samples)


def _loader(ds, workers=2, **kw):
    return DataLoader(ds, batch_size=3, num_workers=workers, **kw)


def test_torch_stream_pickles_and_iterates_the_same(shard_dir):
    d, ids = shard_dir
    for ds in (ShardStream(d, seed=2, transform=item_id), ShardStream.torch(d, seed=2, transform=item_id)):
        again = pickle.loads(pickle.dumps(ds))
        assert type(again) is type(ds)
        assert [x["id"] for x in again] == [x["id"] for x in ds]


@pytest.mark.parametrize("method", ["fork", pytest.param("spawn", marks=pytest.mark.slow),
                                    pytest.param("forkserver", marks=pytest.mark.slow)])
def test_each_start_method_reads_every_item_once(shard_dir, method):
    d, ids = shard_dir
    ds = ShardStream.torch(d, seed=3, num_workers=2, transform=item_id)
    got = [i for b in _loader(ds, multiprocessing_context=method) for i in ids_of(b)]
    assert sorted(got) == ids


def test_persistent_workers_and_set_epoch(shard_dir):
    """Every epoch is full (it used to be empty after the first), in a new order per epoch."""
    d, ids = shard_dir
    ds = ShardStream.torch(d, seed=3, num_workers=2, buffer_size=4, transform=item_id)
    loader = _loader(ds, persistent_workers=True)
    orders = []
    for epoch in range(3):
        ds.set_epoch(epoch)
        got = [i for b in loader for i in ids_of(b)]
        assert sorted(got) == ids, f"epoch {epoch}"
        orders.append(got)
    assert orders[0] != orders[1] != orders[2]
    # the same epoch again (no set_epoch) is read in full, in the same order
    assert [i for b in loader for i in ids_of(b)] == orders[2]
    # and equals a fresh, non-persistent loader on that epoch
    fresh = ShardStream.torch(d, seed=3, num_workers=2, buffer_size=4, transform=item_id, epoch=2)
    assert sorted(i for b in _loader(fresh) for i in ids_of(b)) == sorted(orders[2])


def test_len_is_per_rank(shard_dir):
    d, _ = shard_dir
    lens = [len(ShardStream(d, rank=r, world_size=3)) for r in range(3)]
    assert sum(lens) == N and max(lens) - min(lens) <= 1
    assert [len(list(ShardStream(d, rank=r, world_size=3, shuffle=False))) for r in range(3)] == lens
    assert len(ShardStream(d, mode="qa", rank=0, world_size=2)) == N  # 2N QA pairs over 2 ranks


def test_record_with_default_collate_and_resume(shard_dir):
    d, ids = shard_dir
    make = lambda: ShardStream.torch(d, seed=5, num_workers=2, buffer_size=4, transform=item_id)  # noqa: E731
    ds = make()
    it = iter(_loader(ds))
    head = []
    for _ in range(3):
        b = next(it)
        assert isinstance(b["qa"], torch.Tensor)  # default collate
        ds.record(b)
        head += ids_of(b)
    del it
    state = ds.state_dict()
    assert sum(state["progress"].values()) == len(head) == 9
    ds2 = make()
    ds2.load_state_dict(state)
    rest = [i for b in _loader(ds2) for i in ids_of(b)]
    assert sorted(head + rest) == ids and not set(head) & set(rest)


def test_state_of_another_rank_is_refused(shard_dir):
    """Every rank loading rank 0's checkpoint used to be accepted (and re-read rank 0's data)."""
    d, _ = shard_dir
    r0 = ShardStream(d, rank=0, world_size=2, num_workers=1)
    next(iter(r0))
    state = r0.state_dict()
    assert (state["rank"], state["world_size"], state["num_workers"]) == (0, 2, 1)
    with pytest.raises(ValueError, match="rank 0 of 2"):
        ShardStream(d, rank=1, world_size=2, num_workers=1).load_state_dict(state)
    with pytest.raises(ValueError, match="load_elastic_state"):
        ShardStream(d, rank=0, world_size=3, num_workers=1).load_state_dict(state)
    other = ShardStream(d, rank=0, world_size=2, num_workers=1, buffer_size=7)
    with pytest.raises(ValueError, match="buffer_size"):
        other.load_state_dict(state)


def _read_slots(d, world, workers, states=None, elastic=None, **kw):
    """Per slot: (stream, items read); `states`: per-rank states to load (strict) / `elastic`: all old states."""
    out = []
    for r in range(world):
        for w in range(workers):
            s = ShardStream(d, rank=r, world_size=world, worker=w, num_workers=workers, **kw)
            if elastic is not None:
                s.load_elastic_state(elastic)
            out.append(s)
    return out


@pytest.mark.parametrize("new_world,new_workers", [(3, 1), (1, 2), (2, 2)])
@pytest.mark.parametrize("mode", ["samples", "qa"])
def test_elastic_resume_resplits_the_rest_exactly_once(shard_dir, mode, new_world, new_workers):
    d, _ = shard_dir
    kw = {"mode": mode, "seed": 9, "buffer_size": 3, "epoch": 1}
    every = sorted(x for s in _read_slots(d, 1, 1, **kw) for x in _keys(s))
    old = _read_slots(d, 2, 2, **kw)
    head = []
    for k, s in enumerate(old):  # slot k consumes k + 1 items
        it = iter(s)
        head += [_key(next(it)) for _ in range(k + 1)]
    states = []
    for r in range(2):  # one state per rank: merge the progress of its two worker slots
        st = old[2 * r].state_dict()
        st["num_workers"], st["progress"] = 2, {**old[2 * r].state_dict()["progress"], **old[2 * r + 1].state_dict()["progress"]}
        states.append(st)
    new = _read_slots(d, new_world, new_workers, elastic=states, **kw)
    rest = [x for s in new for x in _keys(s)]
    assert sorted(head + rest) == every and len(head + rest) == len(every)
    assert sum(len(s) for s in new[::new_workers]) == len(rest)  # len() reports the re-split share
    # a checkpoint inside the re-split epoch resumes elastically again
    mid = _read_slots(d, new_world, new_workers, elastic=states, **kw)
    head2 = []
    for s in mid:
        it = iter(s)
        head2 += [_key(x) for _, x in zip(range(2), it)]
    states2 = []
    for r in range(new_world):
        st = mid[r * new_workers].state_dict()
        st["progress"] = {k: v for s in mid[r * new_workers:(r + 1) * new_workers] for k, v in s.state_dict()["progress"].items()}
        states2.append(st)
    last = [x for s in _read_slots(d, 1, 1, elastic=states2, **kw) for x in _keys(s)]
    assert sorted(head + head2 + last) == every
    # the next epoch is whole again, on the new topology
    for s in new:
        s.set_epoch(2)
    assert sorted(x for s in new for x in _keys(s)) == every


def _key(x):
    return x.qa_id if hasattr(x, "qa_id") else x.sample_id


def _keys(stream):
    return [_key(x) for x in stream]


def test_elastic_resume_needs_every_rank(shard_dir):
    d, _ = shard_dir
    st = ShardStream(d, rank=0, world_size=2).state_dict()
    with pytest.raises(ValueError, match="every rank"):
        ShardStream(d).load_elastic_state([st])


def test_damaged_shard_raises_or_is_skipped_and_counted(shard_dir, tmp_path):
    import shutil

    d, ids = shard_dir
    bad = tmp_path / "bad"
    shutil.copytree(d, bad)
    p = bad / "shard-00002.mcap"
    data = bytearray(p.read_bytes())
    data[len(data) // 3] ^= 0x20
    p.write_bytes(bytes(data))
    forget()
    from refspatial_gen.shards import ShardError

    with pytest.raises(ShardError, match="shard-00002.mcap"):
        list(ShardStream(bad, shuffle=False))
    s = ShardStream(bad, shuffle=False, on_error="skip")
    with pytest.warns(UserWarning, match="shard-00002.mcap"):
        got = [x.sample_id for x in s]
    assert len(got) == N - SIZES[2] and list(s.skipped) == ["shard-00002.mcap"]
    assert "hash_mismatch" in s.skipped["shard-00002.mcap"]


@pytest.mark.slow
def test_torchrun_two_processes_gloo(shard_dir, tmp_path):
    d, ids = shard_dir
    out = tmp_path / "ddp.json"
    tests = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tests), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
           str(tests / "helpers" / "stream_ddp.py"), str(d), str(out)]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads(out.read_text())
    for sorted_ids, order in res["epochs"]:
        assert sorted_ids == ids
    assert res["epochs"][0][1] != res["epochs"][1][1]
    assert res["resumed"] == ids and res["resumed_n"] == N
    assert [x[0] for x in res["lens"]] == [N // 2, N - N // 2] and res["state_world"] == 2
