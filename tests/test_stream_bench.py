"""The stream-vs-WebDataset bench runs and reports both sides on the same samples."""

from __future__ import annotations

import pytest


def test_bench_reports_both_readers(tmp_path):
    pytest.importorskip("webdataset")
    from refspatial_gen.shards.bench import make_toy_shards, stream_vs_webdataset

    d = make_toy_shards(tmp_path / "shards", samples=6, width=160, height=120, per_shard=4)
    r = stream_vs_webdataset(d, repeats=1, work_dir=tmp_path / "work")
    assert r["samples"] == 6
    for variant in ("full", "raw"):
        for side in ("stream", "webdataset"):
            assert r[variant][side]["samples_per_s"] > 0 and r[variant][side]["mb_per_s"] > 0
        assert r[variant]["ratio"] > 0
    assert r["ratio"] == r["full"]["ratio"]


@pytest.mark.slow
def test_format_bench_reads_every_format_on_the_same_samples(tmp_path, monkeypatch):
    pytest.importorskip("datasets")
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    from refspatial_gen.shards.bench import FORMATS, format_throughput, make_toy_shards

    d = make_toy_shards(tmp_path / "shards", samples=6, width=96, height=72, per_shard=3)
    formats = [f for f in FORMATS if f != "ray"]  # Ray costs seconds to start; `make bench` includes it
    r = format_throughput(d, formats=formats, repeats=1, work_dir=tmp_path / "work")
    assert r["samples"] == 6
    for f in formats:
        assert r[f]["samples_per_s"] > 0 and r[f]["mb_per_s"] > 0 and r[f]["ratio_to_webdataset"] > 0
    assert r["webdataset"]["ratio_to_webdataset"] == 1.0
