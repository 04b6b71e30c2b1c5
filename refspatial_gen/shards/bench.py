"""Streaming read throughput: our MCAP stream vs the same samples as WebDataset tars, in one run.

Both sides do the same work per sample, with the same decoders: decode view-0 RGB (cv2), load the
float32 depth, parse the QA pairs. A second figure ("raw") skips pixel decoding on both sides, which
isolates the container cost. Files are read once before timing on each side so both come from the
page cache. `python -m refspatial_gen.shards.bench [DIR]` prints the result as JSON.
"""

from __future__ import annotations

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
            wds.handle_extension("rgb0.jpg rgb0.png", decode_image))
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


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv:
        result = stream_vs_webdataset(argv[0])
    else:
        with tempfile.TemporaryDirectory() as t:
            result = stream_vs_webdataset(make_toy_shards(Path(t) / "shards"))
    print(json.dumps(result, indent=1, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
