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
