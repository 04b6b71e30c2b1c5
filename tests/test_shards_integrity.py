"""check_shards, salvage_shard and clear errors for truncated, altered and random-byte shards."""

from __future__ import annotations

import numpy as np
import pytest

from refspatial_gen.shards import ShardError, ShardWriter, read_samples, write_index
from refspatial_gen.shards.integrity import check_shard_file, check_shards, salvage_shard
from refspatial_gen.sources.toy_samples import make_samples


@pytest.fixture(scope="module")
def samples():
    return make_samples(6, seed=11)


def _run_dir(d, samples, chunk_size=64 * 1024):
    w = ShardWriter(d / "shard-00000.mcap", chunk_size=chunk_size)
    for s in samples[:4]:
        w.write(s)
    infos = w.finish()
    w2 = ShardWriter(d / "shard-00001.mcap", chunk_size=chunk_size)
    for s in samples[4:]:
        w2.write(s)
    infos += w2.finish()
    write_index(d, [i.to_dict() for i in infos], {"seed": 1, "code_version": "t"})
    return infos


def test_clean_dir_has_no_problems(tmp_path, samples):
    _run_dir(tmp_path, samples)
    assert check_shards(tmp_path) == []
    assert check_shards(tmp_path, deep=True) == []


def test_hash_mismatch_names_file(tmp_path, samples):
    _run_dir(tmp_path, samples)
    p = tmp_path / "shard-00001.mcap"
    data = bytearray(p.read_bytes())
    data[len(data) // 2] ^= 0xFF
    p.write_bytes(bytes(data))
    probs = check_shards(tmp_path)
    assert [(q["file"], q["problem"]) for q in probs] == [(str(p), "hash_mismatch")]
    assert "sha256" in probs[0]["detail"]


def test_truncated_shard(tmp_path, samples):
    _run_dir(tmp_path, samples)
    p = tmp_path / "shard-00000.mcap"
    p.write_bytes(p.read_bytes()[: p.stat().st_size * 2 // 3])
    probs = check_shards(tmp_path)
    assert probs[0]["file"] == str(p) and probs[0]["problem"] == "size_mismatch"
    with pytest.raises(ShardError, match="truncated") as e:
        list(read_samples(p))
    assert str(p) in str(e.value)


def test_random_bytes_file(tmp_path):
    p = tmp_path / "junk.mcap"
    p.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(ShardError, match="not an MCAP file") as e:
        list(read_samples(p))
    assert str(p) in str(e.value)
    with pytest.raises(ShardError, match="not an MCAP file"):
        salvage_shard(p)
    with pytest.raises(ShardError):
        check_shard_file(p)


def test_random_bytes_after_valid_magic(tmp_path):
    p = tmp_path / "junk2.mcap"
    p.write_bytes(b"\x89MCAP0\r\n" + np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(ShardError) as e:
        list(read_samples(p))
    assert str(p) in str(e.value)


def test_unfinished_and_unlisted_are_reported(tmp_path, samples):
    _run_dir(tmp_path, samples)
    (tmp_path / "shard-00002.mcap.partial").write_bytes(b"\x89MCAP0\r\n")
    (tmp_path / "extra.mcap").write_bytes(b"")
    (tmp_path / "shard-00001.mcap").unlink()
    kinds = sorted(q["problem"] for q in check_shards(tmp_path))
    assert kinds == ["missing", "unfinished", "unlisted"]


def test_no_index(tmp_path):
    probs = check_shards(tmp_path)
    assert probs[0]["problem"] == "index_unreadable" and "index.json" in probs[0]["detail"]


@pytest.mark.parametrize("fraction", [0.3, 0.6, 0.9, 0.97])
def test_salvage_recovers_complete_samples(tmp_path, samples, fraction):
    """Cut a finished shard at a point before its footer (what a crash leaves) and salvage it."""
    full = tmp_path / "full" / "shard-00000.mcap"
    w = ShardWriter(full, chunk_size=64 * 1024, image_format="png")
    for s in samples:
        w.write(s)
    w.finish()
    data = full.read_bytes()
    partial = tmp_path / "shard-00000.mcap.partial"
    partial.write_bytes(data[: int(len(data) * fraction)])
    info = salvage_shard(partial)
    out = tmp_path / "shard-00000.mcap"
    assert info["path"] == str(out) and out.is_file() and not partial.exists()
    got = list(read_samples(out))
    k = len(got)
    assert 1 <= k <= len(samples) and info["samples"] == k
    for a, b in zip(samples, got):  # a prefix, intact
        assert a.sample_id == b.sample_id
        assert np.array_equal(a.frames[0].rgb, b.frames[0].rgb)
        assert np.array_equal(a.frames[0].depth, b.frames[0].depth)
    # the salvaged file equals what the writer makes for exactly those samples
    ref = tmp_path / "ref" / "shard-00000.mcap"
    w = ShardWriter(ref, image_format="png")
    for s in samples[:k]:
        w.write(s)
    w.finish()
    assert ref.read_bytes() == out.read_bytes()


def test_salvage_of_writer_left_open(tmp_path, samples):
    """The writer's .partial as the process leaves it (chunks flushed, no footer)."""
    w = ShardWriter(tmp_path / "shard-00005.mcap", chunk_size=64 * 1024)
    for s in samples:
        w.write(s)
    w._part.f.flush()  # what the OS has after the process is killed
    import shutil

    shutil.copy(tmp_path / "shard-00005.mcap.partial", tmp_path / "copy.mcap.partial")
    w.abort()
    info = salvage_shard(tmp_path / "copy.mcap.partial")
    assert info["samples"] >= len(samples) - 1
    assert [s.sample_id for s in read_samples(info["path"])] == [s.sample_id for s in samples[: info["samples"]]]


def test_salvage_nothing_recoverable(tmp_path):
    p = tmp_path / "x.mcap.partial"
    p.write_bytes(b"\x89MCAP0\r\n\x01")
    with pytest.raises(ShardError, match="no complete sample"):
        salvage_shard(p)
    assert p.exists() and not (tmp_path / "x.mcap").exists()
