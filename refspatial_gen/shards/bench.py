"""Streaming read throughput: our MCAP stream vs the same samples as WebDataset tars, in one run.

Both sides do the same work per sample, with the same decoders: decode view-0 RGB (cv2), load the
float32 depth, parse the QA pairs. A second figure ("raw") skips pixel decoding on both sides, which
isolates the container cost. Files are read once before timing on each side so both come from the
page cache. `format_throughput` does the same for every export format (WebDataset, HF Parquet through
`datasets` and Ray Data, the RefSpatial and JSONL folders) against the MCAP stream, on the same samples.
`python -m refspatial_gen.shards.bench [DIR]` prints both as JSON.
"""

from __future__ import annotations

import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _dir_bytes(paths) -> int:
    return sum(Path(p).stat().st_size for p in paths)


def _time(fn, repeats: int) -> tuple[float, int]:
    best, n = float("inf"), 0
    for _ in range(repeats):
        t = time.perf_counter()
        n = fn()
        best = min(best, time.perf_counter() - t)
    return best, n


def make_toy_shards(out: Path, samples: int = 48, width: int = 640, height: int = 480, per_shard: int = 16) -> Path:
    """Shards of toy samples at the simulated source's resolution (for a bench with no run output)."""
    from refspatial_gen.shards import ShardWriter, write_index
    from refspatial_gen.sources.toy_samples import make_sample

    rng = np.random.default_rng(0)
    infos = []
    for k in range(0, samples, per_shard):
        w = ShardWriter(out / f"shard-{k // per_shard:05d}.mcap")
        for i in range(k, min(samples, k + per_shard)):
            w.write(make_sample(rng, i, width=width, height=height, n_qa=8))
        infos += w.finish()
    write_index(out, [i.to_dict() for i in infos], {"seed": 0, "bench": True})
    return out


def stream_vs_webdataset(shard_dir: Path | str, *, repeats: int = 3, work_dir: Path | str | None = None) -> dict:
    """{stream: {samples_per_s, mb_per_s}, webdataset: {...}, ratio, raw: {...}} for one shard directory."""
    import webdataset as wds

    from refspatial_gen.core.serialize import decode_image
    from refspatial_gen.shards.export import export
    from refspatial_gen.shards.index import shard_paths
    from refspatial_gen.stream import ShardStream

    shard_dir = Path(shard_dir)
    tmp = tempfile.TemporaryDirectory() if work_dir is None else None
    wdir = Path(tmp.name if tmp else work_dir) / "wds"
    res = export(shard_dir, "webdataset", wdir)
    tars = [str(wdir / t) for t in res["tars"]]
    mcap_bytes, tar_bytes = _dir_bytes(shard_paths(shard_dir)), _dir_bytes(tars)

    def ours_full() -> int:
        n = 0
        for it in ShardStream(shard_dir, shuffle=False):
            rgb, depth, qa = it.rgb(0), it.depth(0), it.qa
            n += rgb.shape[0] > 0 and depth.shape[0] > 0 and len(qa) >= 0
        return n

    def theirs_full() -> int:
        ds = wds.WebDataset(tars, shardshuffle=False, empty_check=False).decode(
            wds.handle_extension("rgb0.jpg rgb0.png", decode_image)
        )
        n = 0
        for rec in ds:
            rgb, depth, qa = rec.get("rgb0.jpg", rec.get("rgb0.png")), rec["depth0.npy"], rec["json"]["qa"]
            n += rgb.shape[0] > 0 and depth.shape[0] > 0 and len(qa) >= 0
        return n

    def ours_raw() -> int:
        n = 0
        for it in ShardStream(shard_dir, shuffle=False):
            data, _ = it.image_bytes(0)
            n += len(data) > 0 and len(it.qa) >= 0
        return n

    def theirs_raw() -> int:
        n = 0
        for rec in wds.WebDataset(tars, shardshuffle=False, empty_check=False):
            data = rec.get("rgb0.jpg", rec.get("rgb0.png"))
            n += len(data) > 0 and len(json.loads(rec["json"])["qa"]) >= 0
        return n

    out: dict = {"samples": res["samples"], "mcap_mb": round(mcap_bytes / 1e6, 2), "tar_mb": round(tar_bytes / 1e6, 2)}
    for label, a, b in (("full", ours_full, theirs_full), ("raw", ours_raw, theirs_raw)):
        a(), b()  # warm the page cache and imports
        ta, na = _time(a, repeats)
        tb, nb = _time(b, repeats)
        if na != nb or na != res["samples"]:
            raise RuntimeError(f"bench read {na} samples from MCAP and {nb} from WebDataset, expected {res['samples']}")
        out[label] = {
            "stream": {"samples_per_s": round(na / ta, 1), "mb_per_s": round(mcap_bytes / ta / 1e6, 1)},
            "webdataset": {"samples_per_s": round(nb / tb, 1), "mb_per_s": round(tar_bytes / tb / 1e6, 1)},
            "ratio": round(tb / ta, 3),
        }
    out["ratio"] = out["full"]["ratio"]
    if tmp:
        tmp.cleanup()
    return out


FORMATS = ("mcap_stream", "webdataset", "hf", "hf_streaming", "refspatial", "jsonl", "ray")


def _ok(rgb, depth, qa) -> int:
    return int(rgb.shape[0] > 0 and (depth is None or depth.shape[0] > 0) and len(qa) >= 0)


def _tiff(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)), dtype=np.float32)


def _hf_rows(rows) -> int:
    from refspatial_gen.core.serialize import decode_image

    return sum(_ok(decode_image(r["images"][0]["bytes"]), _tiff(r["depth"][0]["bytes"]), r["qa"]) for r in rows)


def _hf_dataset(out: Path, streaming: bool):
    import datasets

    datasets.disable_progress_bars()
    ds = datasets.load_dataset(str(out), split="train", streaming=streaming, cache_dir=str(out.parent / "hf-cache"))
    raw = datasets.List(datasets.Image(decode=False))
    return ds.cast_column("images", raw).cast_column("depth", raw)


def _file_samples(out: Path, recs: list[tuple[str, str | None, list]]) -> int:
    """Per sample (first image of a record, once): decode the image (and depth map) files, count its QA."""
    import cv2

    seen: dict[str, tuple[str | None, int]] = {}
    for img, dep, qa in recs:
        d, n = seen.get(img, (dep, 0))
        seen[img] = (d, n + len(qa))
    n = 0
    for img, (dep, q) in seen.items():
        rgb = cv2.imread(str(out / "image" / img), cv2.IMREAD_COLOR)
        depth = None if dep is None else cv2.imread(str(out / "depth" / dep), cv2.IMREAD_UNCHANGED)
        n += _ok(rgb, depth, range(q))
    return n


def _reader(fmt: str, shard_dir: Path, out: Path | None):
    """A function reading every sample of the export once with the format's own library; returns the count."""
    from refspatial_gen.core.serialize import decode_image

    if fmt == "mcap_stream":
        from refspatial_gen.stream import ShardStream

        return lambda: sum(_ok(it.rgb(0), it.depth(0), it.qa) for it in ShardStream(shard_dir, shuffle=False))
    if fmt == "webdataset":
        import webdataset as wds

        tars = [str(out / t) for t in json.loads((out / "manifest.json").read_text())["tars"]]
        return lambda: sum(
            _ok(
                decode_image(r.get("rgb0.jpg", r.get("rgb0.png"))),
                np.load(io.BytesIO(r["depth0.npy"])),
                json.loads(r["json"])["qa"],
            )
            for r in wds.WebDataset(tars, shardshuffle=False, empty_check=False)
        )
    if fmt in ("hf", "hf_streaming"):
        ds = _hf_dataset(out, fmt == "hf_streaming")
        return lambda: _hf_rows(ds)
    if fmt == "ray":
        import ray

        if not ray.is_initialized():
            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
        return lambda: _hf_rows(ray.data.read_parquet(str(out / "data")).iter_rows())
    if fmt == "refspatial":

        def read() -> int:
            recs = [
                (r["image"][0], r["depth"][0], r["conversations"][::2])
                for f in sorted(out.glob("*.json"))
                for r in json.loads(f.read_text())
            ]
            return _file_samples(out, recs)

        return read
    if fmt == "jsonl":

        def read_jsonl() -> int:
            lines = [json.loads(x) for x in (out / "qa.jsonl").read_text().splitlines()]
            return _file_samples(out, [(x["image"][0], None, [x]) for x in lines if "_marks" not in x["image"][0]])

        return read_jsonl
    raise ValueError(f"unknown format {fmt!r}")


def _export_dir(fmt: str) -> str | None:
    return {"mcap_stream": None, "hf_streaming": "hf", "ray": "hf"}.get(fmt, fmt)


def format_throughput(
    shard_dir: Path | str, *, formats=FORMATS, repeats: int = 3, work_dir: Path | str | None = None
) -> dict:
    """Read throughput of every format on the same samples: {format: {samples_per_s, mb_per_s, ratio}}.

    Each format is exported from `shard_dir`, then read by its own library doing the same work per
    sample (decode view-0 RGB with OpenCV, load its depth, parse the QA pairs; RefSpatial's depth is
    the 8-bit PNG it stores, JSONL has none); best of `repeats` after one warm-up pass. MB/s are of the
    format's files; ratio = samples/s over WebDataset's. A format whose library is missing is skipped.
    """
    from refspatial_gen.shards.export import RawSource, export
    from refspatial_gen.shards.index import shard_paths

    shard_dir = Path(shard_dir)
    tmp = tempfile.TemporaryDirectory() if work_dir is None else None
    work = Path(tmp.name if tmp else work_dir)
    expected = len(RawSource(shard_dir))
    out: dict = {"samples": expected}
    made: dict[str, Path] = {}
    try:
        for fmt in formats:
            sub = _export_dir(fmt)
            try:
                if sub is not None and sub not in made:
                    made[sub] = work / sub
                    export(shard_dir, sub, made[sub], overwrite=True)
                files = (
                    shard_paths(shard_dir)
                    if sub is None
                    else [p for p in made[sub].rglob("*") if p.is_file() and "hf-cache" not in p.parts]
                )
                fn = _reader(fmt, shard_dir, made.get(sub))
            except ImportError as e:
                out[fmt] = {"skipped": f"needs {e.name}"}
                continue
            fn()  # warm-up: page cache, imports, the hf Arrow cache
            t, n = _time(fn, repeats)
            if n != expected:
                raise RuntimeError(f"{fmt}: read {n} samples, expected {expected}")
            out[fmt] = {
                "samples_per_s": round(n / t, 1),
                "mb_per_s": round(_dir_bytes(files) / t / 1e6, 1),
                "mb": round(_dir_bytes(files) / 1e6, 2),
            }
    finally:
        if "ray" in sys.modules and sys.modules["ray"].is_initialized():
            sys.modules["ray"].shutdown()
        if tmp:
            tmp.cleanup()
    base = out.get("webdataset", {}).get("samples_per_s")
    for fmt in formats:
        if base and "samples_per_s" in out.get(fmt, {}):
            out[fmt]["ratio_to_webdataset"] = round(out[fmt]["samples_per_s"] / base, 3)
    return out


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv:
        result = {"stream_vs_webdataset": stream_vs_webdataset(argv[0]), "formats": format_throughput(argv[0])}
    else:
        with tempfile.TemporaryDirectory() as t:
            d = make_toy_shards(Path(t) / "shards")
            result = {"stream_vs_webdataset": stream_vs_webdataset(d), "formats": format_throughput(d)}
    print(json.dumps(result, indent=1, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
