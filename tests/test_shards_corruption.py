"""Damaged shards and edited indexes are caught by every reader, with the file named and no traceback.

Covers #22 defect 2 (the stream, inspect, preview and `export --no-check` read a flipped byte silently)
and #16 items 2 (a shard name in index.json reaching outside the folder) and 8 (`stats` traceback on a
corrupt shard, `verify` passing edited sample counts).
"""

from __future__ import annotations

import json
import shutil
import struct

import pytest

from refspatial_gen.cli import main
from refspatial_gen.shards import ShardError, ShardWriter, iter_raw, read_index, read_samples, write_index
from refspatial_gen.sources.toy_samples import make_samples
from refspatial_gen.shards.trust import forget

SHARD = "shard-00000.mcap"


@pytest.fixture(scope="module")
def clean_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("clean")
    samples = make_samples(5, seed=41, width=160, height=120, n_qa=3)
    infos = []
    for name, part in ((SHARD, samples[:3]), ("shard-00001.mcap", samples[3:])):
        w = ShardWriter(d / name, chunk_size=64 * 1024, image_format="png")
        for s in part:
            w.write(s)
        infos += w.finish()
    n, q = len(samples), sum(len(s.qa) for s in samples)
    stats = {"samples": n, "qa_pairs": q, "by_relation": {}, "by_family": {}, "by_steps": {}, "by_source": {"toy": n},
             "dropped": {}, "units": n}
    write_index(d, [i.to_dict() for i in infos], {"seed": 0, "stats": stats})
    return d


def _record_starts(data: bytes) -> dict[int, int]:
    """{opcode: first byte offset} of the top-level records of an MCAP file."""
    out, pos = {}, 8
    while pos < len(data) - 8:
        op, length = struct.unpack_from("<BQ", data, pos)
        out.setdefault(op, pos)
        pos += 9 + length
    return out


def _offsets(path) -> dict[str, int]:
    data = path.read_bytes()
    rec = _record_starts(data)
    return {"magic": 3, "header": rec[0x01] + 12, "chunk_head": rec[0x06] + 20, "chunk_data": rec[0x06] + 400,
            "middle": len(data) // 2, "message_index": rec[0x07] + 10, "data_end_crc": rec[0x0F] + 10,
            "summary": rec[0x0F] + 60, "footer_crc": len(data) - 10, "closing_magic": len(data) - 3}


OFFSETS = ["magic", "header", "chunk_head", "chunk_data", "middle", "message_index", "data_end_crc", "summary",
           "footer_crc", "closing_magic"]


def _flipped(clean_dir, tmp_path, where: str):
    d = tmp_path / "ds"
    shutil.copytree(clean_dir, d)
    p = d / SHARD
    data = bytearray(p.read_bytes())
    data[_offsets(p)[where]] ^= 0x04
    p.write_bytes(bytes(data))
    forget()  # a fresh process's view: nothing verified yet
    return d, p


def _reader_stream(d, p, tmp_path, capsys):
    from refspatial_gen.stream import ShardStream

    with pytest.raises(ShardError) as e:
        for it in ShardStream(d, shuffle=False):
            it.rgb(0)
    return str(e.value)


def _reader_read_samples(d, p, tmp_path, capsys):
    with pytest.raises(ShardError) as e:
        list(read_samples(p))
    return str(e.value)


def _cli(argv, code=1):
    def run(d, p, tmp_path, capsys):
        args = [a.format(d=d, p=p, t=tmp_path) for a in argv]
        assert main(args) == code
        cap = capsys.readouterr()
        assert "Traceback" not in cap.err
        return cap.out + cap.err
    return run


READERS = {
    "read_samples": _reader_read_samples,
    "stream": _reader_stream,
    "inspect": _cli(["inspect", "{p}"]),
    "preview": _cli(["preview", "{d}", "--out", "{t}/preview", "--n", "4"]),
    "export_no_check": _cli(["export", "{d}", "--format", "jsonl", "--out", "{t}/j", "--no-check"]),
    "export": _cli(["export", "{d}", "--format", "webdataset", "--out", "{t}/w"]),
    "stats": _cli(["stats", "{d}"]),
    "verify": _cli(["verify", "{d}"]),
}


@pytest.mark.parametrize("where", OFFSETS)
@pytest.mark.parametrize("reader", sorted(READERS))
def test_byte_flip_is_caught_by_every_reader(clean_dir, tmp_path, capsys, reader, where):
    d, p = _flipped(clean_dir, tmp_path, where)
    msg = READERS[reader](d, p, tmp_path, capsys)
    assert str(p) in msg
    assert any(k in msg for k in ("mismatch", "corrupt", "invalid", "truncated")), msg


@pytest.mark.parametrize("where", OFFSETS)
def test_byte_flip_without_index_is_caught_by_crcs(clean_dir, tmp_path, where):
    """A shard on its own (no index.json to compare with): the MCAP CRCs catch every flip."""
    d, p = _flipped(clean_dir, tmp_path, where)
    (d / "index.json").unlink()
    with pytest.raises(ShardError) as e:
        list(iter_raw(p))
    assert str(p) in str(e.value)


@pytest.mark.parametrize("stride", [29, pytest.param(1, marks=pytest.mark.slow)])
def test_every_byte_of_a_small_shard_is_caught_by_crcs(tmp_path, stride):
    """On a small file (every 29th byte; every byte in the slow suite): flipping a byte is reported
    with no index to help."""
    p = tmp_path / "s.mcap"
    w = ShardWriter(p, chunk_size=8 * 1024)
    for s in make_samples(1, seed=2, width=32, height=24, n_qa=1):
        w.write(s)
    w.finish()
    data = p.read_bytes()
    q = tmp_path / "f.mcap"
    missed = []
    for off in range(0, len(data), stride):
        b = bytearray(data)
        b[off] ^= 0x01
        q.write_bytes(bytes(b))
        try:
            list(iter_raw(q))
            missed.append(off)
        except ShardError:
            pass
    assert missed == []


def test_clean_dir_reads_everywhere(clean_dir, tmp_path, capsys):
    forget()
    assert main(["stats", str(clean_dir)]) == 0
    assert main(["inspect", str(clean_dir / SHARD)]) == 0
    assert main(["export", str(clean_dir), "--format", "jsonl", "--out", str(tmp_path / "j"), "--no-check"]) == 0
    capsys.readouterr()
    main(["verify", str(clean_dir), "--json"])  # toy QA programs do not re-evaluate: only the shard part matters
    res = json.loads(capsys.readouterr().out)
    assert res["shard_problems"] == [] and res["qa_pairs"] == 15


def test_official_reader_agrees_flips_are_damage(clean_dir, tmp_path):
    """The official reader with CRC checks rejects the same flipped chunk (ours is not stricter than MCAP)."""
    from mcap.reader import make_reader

    _, p = _flipped(clean_dir, tmp_path, "chunk_data")
    with open(p, "rb") as f, pytest.raises(Exception):
        list(make_reader(f, validate_crcs=True).iter_messages())


@pytest.mark.parametrize("name", ["../../etc/passwd", "/etc/passwd", "..", "sub/shard.mcap", "a\\b.mcap", "", 7])
def test_index_shard_names_are_confined(clean_dir, tmp_path, capsys, name):
    d = tmp_path / "ds"
    shutil.copytree(clean_dir, d)
    idx = json.loads((d / "index.json").read_text())
    idx["shards"][0]["name"] = name
    (d / "index.json").write_text(json.dumps(idx))
    with pytest.raises(ValueError, match="index.json") as e:
        read_index(d)
    assert "refusing" in str(e.value)
    from refspatial_gen.stream import ShardStream

    with pytest.raises(ValueError, match="index.json"):
        ShardStream(d)
    for argv in (["stats", str(d)], ["export", str(d), "--format", "jsonl", "--out", str(tmp_path / "x"), "--no-check"],
                 ["verify", str(d)]):
        assert main(argv) != 0
        err = capsys.readouterr().err
        assert "index.json" in err and "Traceback" not in err


def test_write_index_refuses_unsafe_names(tmp_path):
    row = {"name": "../x.mcap", "samples": 0, "qa_pairs": 0, "bytes": 0, "sha256": ""}
    with pytest.raises(ValueError, match="name"):
        write_index(tmp_path, [row], {})


def test_verify_catches_edited_counts(clean_dir, tmp_path, capsys):
    """#16.8: an index whose sample counts were edited (row, totals and stats kept consistent) fails verify."""
    d = tmp_path / "ds"
    shutil.copytree(clean_dir, d)
    idx = json.loads((d / "index.json").read_text())
    idx["shards"][0]["samples"] += 2
    idx["totals"]["samples"] += 2
    idx["stats"]["samples"] += 2
    (d / "index.json").write_text(json.dumps(idx))
    assert main(["verify", str(d)]) == 1
    out = capsys.readouterr().out
    assert f"{d / SHARD}: count_mismatch" in out


def test_totals_that_do_not_add_up_are_reported(clean_dir, tmp_path, capsys):
    d = tmp_path / "ds"
    shutil.copytree(clean_dir, d)
    idx = json.loads((d / "index.json").read_text())
    idx["totals"]["qa_pairs"] = 999
    (d / "index.json").write_text(json.dumps(idx))
    assert main(["stats", str(d)]) == 1
    assert "totals.qa_pairs is 999" in capsys.readouterr().err
    assert main(["verify", str(d)]) == 1


def test_stats_on_missing_or_broken_index_has_no_traceback(tmp_path, capsys):
    assert main(["stats", str(tmp_path)]) == 2
    (tmp_path / "index.json").write_text("{not json")
    assert main(["stats", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "index.json" in err and "Traceback" not in err


def test_hash_checked_once_per_process(clean_dir, monkeypatch):
    """The stream hashes each shard once, however many epochs and readers touch it in this process."""
    from refspatial_gen.shards import trust
    from refspatial_gen.stream import ShardStream

    forget()
    calls = []
    real = trust.sha256_file
    monkeypatch.setattr(trust, "sha256_file", lambda p: calls.append(p) or real(p))
    s = ShardStream(clean_dir, shuffle=False)
    for epoch in range(3):
        s.set_epoch(epoch)
        assert len(list(s)) == 5
    list(read_samples(clean_dir / SHARD))
    assert sorted(p.name for p in calls) == [SHARD, "shard-00001.mcap"]


def test_replaced_file_is_hashed_again(clean_dir, tmp_path):
    d = tmp_path / "ds"
    shutil.copytree(clean_dir, d)
    forget()
    list(read_samples(d / SHARD))
    other = make_samples(3, seed=99, width=160, height=120)
    w = ShardWriter(tmp_path / "other.mcap", chunk_size=64 * 1024, image_format="png")
    for s in other:
        w.write(s)
    w.finish()
    shutil.copy(tmp_path / "other.mcap", d / SHARD)
    with pytest.raises(ShardError, match="mismatch"):
        list(read_samples(d / SHARD))
