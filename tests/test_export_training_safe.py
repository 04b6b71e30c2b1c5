"""The training exporters (sft, rft, refspatial-bench) use the shared safe-output helpers: one file per
sample even when two ids look alike once made file-safe, no write into an earlier export, no half export."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys

import pytest

from refspatial_gen.cli import main
from refspatial_gen.shards import ShardWriter, iter_raw, write_index
from refspatial_gen.shards.export import export
from refspatial_gen.shards.export_files import sample_stem
from refspatial_gen.sources.toy_samples import make_samples

FORMATS = ("sft", "rft", "refspatial-bench")


def _write_dir(d, samples):
    w = ShardWriter(d / "shard-00000.mcap", image_format="png")
    for s in samples:
        w.write(s)
    write_index(d, [i.to_dict() for i in w.finish()], {"seed": 0})
    return d


def _sha(p) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def lookalikes(tmp_path_factory):
    """Three samples; two ids differ only in characters a file name cannot hold (old rft: both 'sc_ne_a_b')."""
    samples = make_samples(3, seed=11, width=64, height=48)
    for s, sid in zip(samples, ("scène:a/b", "scène:a:b", "plain-id")):
        s.sample_id = sid
    return _write_dir(tmp_path_factory.mktemp("ds"), samples)


def test_rft_gives_lookalike_ids_their_own_images(lookalikes, tmp_path):
    """Failed on the old code: the second id's image was skipped (same name) and its lines named the first's."""
    stored = {(r.header["sample_id"], v): hashlib.sha256(r.image_bytes(v)[0]).hexdigest()
              for r in iter_raw(lookalikes / "shard-00000.mcap") for v in range(r.views)}
    out = tmp_path / "rft"
    export(lookalikes, "rft", out)
    lines = [json.loads(x) for x in (out / "rft.jsonl").read_text().splitlines()]
    assert len({p.name for p in (out / "image").iterdir()}) == 3
    assert {x["sample_id"] for x in lines} == {"scène:a/b", "scène:a:b", "plain-id"}
    for x in lines:
        assert x["images"] == [f"{sample_stem(x['sample_id'])}_v0.png"]
        assert _sha(out / "image" / x["images"][0]) == stored[(x["sample_id"], 0)]


def test_sft_and_bench_give_lookalike_ids_their_own_images(lookalikes, tmp_path):
    export(lookalikes, "sft", tmp_path / "sft")
    recs = [r for f in (tmp_path / "sft").glob("*.json") for r in json.loads(f.read_text())]
    assert {im for r in recs for im in r["image"]} == {f"{sample_stem(s)}_v0.png" for s in ("scène:a/b", "scène:a:b", "plain-id")}
    export(lookalikes, "refspatial-bench", tmp_path / "bench")
    rows = json.loads((tmp_path / "bench" / "Location" / "question.json").read_text())
    assert len({r["qa_id"].split(":q")[0] for r in rows}) >= 2 and len({r["rgb_path"] for r in rows}) == len(rows)


def test_rft_check_catches_an_image_of_another_sample(lookalikes, tmp_path, monkeypatch):
    """The export's own check compares every line's image with its sample's stored view."""
    import refspatial_gen.shards.export_rft as rft
    from refspatial_gen.shards.export_files import ExportError

    real = rft.write_new
    first: list[bytes] = []

    def swap(path, data):  # every image gets the first sample's pixels
        first.append(data)
        real(path, first[0])

    monkeypatch.setattr(rft, "write_new", swap)
    with pytest.raises(ExportError, match="differs from the stored view"):
        export(lookalikes, "rft", tmp_path / "out")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_existing_output_is_refused_without_overwrite(lookalikes, tmp_path, capsys, fmt):
    out = tmp_path / "out"
    assert main(["export", str(lookalikes), "--format", fmt, "--out", str(out)]) == 0
    before = {p: _sha(p) for p in out.rglob("*") if p.is_file()}
    assert before
    assert main(["export", str(lookalikes), "--format", fmt, "--out", str(out)]) == 1
    assert "not empty" in capsys.readouterr().err
    assert {p: _sha(p) for p in out.rglob("*") if p.is_file()} == before
    assert main(["export", str(lookalikes), "--format", fmt, "--out", str(out), "--overwrite"]) == 0


KILL = """
import os, signal, sys
from refspatial_gen.shards import export_files, export_refspatial, export_refspatial_bench, export_rft
from refspatial_gen.shards.export import export
real, n = export_files.write_new, [0]
def dying(path, data):
    real(path, data)
    n[0] += 1
    if n[0] == 2:
        os.kill(os.getpid(), signal.SIGKILL)
for m in (export_refspatial, export_refspatial_bench, export_rft):
    m.write_new = dying
export(sys.argv[1], sys.argv[2], sys.argv[3])
"""


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_killed_export_leaves_no_half_output(lookalikes, tmp_path, fmt):
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-c", KILL, str(lookalikes), fmt, str(out)], capture_output=True, text=True)
    assert r.returncode == -9, r.stderr
    assert not out.exists()  # the half export lies only in the hidden .out.partial-<pid> folder
    assert main(["export", str(lookalikes), "--format", fmt, "--out", str(out)]) == 0
    assert any(out.rglob("*.json")) or (out / "rft.jsonl").is_file()
