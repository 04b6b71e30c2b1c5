"""Export to WebDataset tar shards (readable by `webdataset.WebDataset` and HF `load_dataset("webdataset")`).

One tar member group per sample, keyed by its file-system-safe stem (no dots: WebDataset keys end at
the first dot):
  <key>.rgb<v>.jpg|png   the stored RGB bytes of view v (no re-encoding)
  <key>.depth<v>.npy     float32 metric depth of view v (lossless)
  <key>.json             the typed sample record (shards.records.sample_record)
Tars hold `samples_per_shard` samples; the default splits a small export into about 16 tars (so each
worker of 2 ranks x 8 DataLoader workers gets one) and caps a tar at 256 samples (about 0.7 GB at
640x480 with depth). Tars are written with fixed member metadata (mtime 0, uid/gid 0, no user names),
so the same shards give the same tar bytes.
"""

from __future__ import annotations

import io
import json
import math
import tarfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from refspatial_gen.core.serialize import dumps
from refspatial_gen.shards.export_files import EXT, StemRegistry, sha256, stored_image_hashes
from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.records import sample_record

TARGET_SHARDS = 16
MAX_SAMPLES_PER_SHARD = 256


def default_samples_per_shard(total: int | None) -> int:
    """About TARGET_SHARDS shards for a small export, at most MAX_SAMPLES_PER_SHARD samples each."""
    if not total:
        return MAX_SAMPLES_PER_SHARD
    return max(1, min(MAX_SAMPLES_PER_SHARD, math.ceil(total / TARGET_SHARDS)))


def _add(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    ti = tarfile.TarInfo(name)
    ti.size, ti.mtime, ti.mode, ti.uid, ti.gid, ti.uname, ti.gname = len(data), 0, 0o644, 0, 0, "", ""
    tar.addfile(ti, io.BytesIO(data))


def npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


def sample_members(raw: RawSample, key: str) -> list[tuple[str, bytes]]:
    out = []
    for v in range(int(raw.header["views"])):
        data, fmt = raw.image_bytes(v)
        out.append((f"{key}.rgb{v}.{EXT.get(fmt, fmt)}", data))
        out.append((f"{key}.depth{v}.npy", npy_bytes(raw.depth(v))))
    out.append((f"{key}.json", dumps(sample_record(raw))))
    return out


def export_webdataset(raws: Iterable[RawSample], out: Path | str, *, samples_per_shard: int | None = None) -> dict:
    """Write `out/wds-00000.tar`, ... and `manifest.json`; returns {"tars": [names], "samples": n, "bytes": total}."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    per = int(samples_per_shard or default_samples_per_shard(len(raws) if hasattr(raws, "__len__") else None))
    if per < 1:
        raise ValueError(f"samples_per_shard must be >= 1, got {per}")
    tars: list[dict] = []
    tar = None
    stems = StemRegistry()
    n = 0
    try:
        for raw in raws:
            if n % per == 0:
                if tar is not None:
                    tar.close()
                tars.append({"name": f"wds-{len(tars):05d}.tar", "samples": 0})
                tar = tarfile.open(out / tars[-1]["name"], "x", format=tarfile.USTAR_FORMAT)
            for name, data in sample_members(raw, stems.claim(raw.header["sample_id"], allow_dot=False)):
                _add(tar, name, data)
            tars[-1]["samples"] += 1
            n += 1
    finally:
        if tar is not None:
            tar.close()
    (out / "manifest.json").write_text(
        json.dumps(
            {"tars": [t["name"] for t in tars], "samples": n, "samples_per_tar": [t["samples"] for t in tars]},
            sort_keys=True,
        )
    )
    return {
        "tars": [t["name"] for t in tars],
        "samples": n,
        "bytes": sum((out / t["name"]).stat().st_size for t in tars),
    }


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """Every sample is in the tars once, with the stored image bytes and depth of each of its views."""
    out = Path(out)
    depth_want: dict[tuple[str, int], str] = {}
    stored = stored_image_hashes(
        raws, lambda raw, stem, v: depth_want.__setitem__((raw.header["sample_id"], v), sha256(npy_bytes(raw.depth(v))))
    )
    want_rgb = {sv: h for h, sv in stored.values()}
    groups: dict[str, dict[str, bytes]] = {}
    problems: list[str] = []
    for t in json.loads((out / "manifest.json").read_text())["tars"]:
        with tarfile.open(out / t) as tf:
            for m in tf.getmembers():
                key, _, kind = m.name.partition(".")
                if key in groups and kind in groups[key]:
                    problems.append(f"{out / t}: member {m.name} appears twice")
                groups.setdefault(key, {})[kind] = tf.extractfile(m).read()
    seen: set[tuple[str, int, str]] = set()
    for key, g in sorted(groups.items()):
        try:
            sid = json.loads(g["json"])["sample_id"]
        except (KeyError, ValueError) as e:
            problems.append(f"{out}: sample {key} has no readable json ({e})")
            continue
        for kind, data in g.items():
            if kind.startswith("rgb"):
                v = int(kind[3:].split(".")[0])
                seen.add((sid, v, "rgb"))
                if want_rgb.get((sid, v)) != sha256(data):
                    problems.append(f"{out}: {key}.{kind} is not the stored image of {sid!r} view {v}")
            elif kind.startswith("depth"):
                v = int(kind[5:].split(".")[0])
                seen.add((sid, v, "depth"))
                if depth_want.get((sid, v)) != sha256(data):
                    problems.append(f"{out}: {key}.{kind} is not the stored depth of {sid!r} view {v}")
    missing = {(sid, v, k) for sid, v in want_rgb for k in ("rgb", "depth")} - seen
    if missing:
        problems.append(f"{out}: {len(missing)} stored views are not in the tars (e.g. {sorted(missing)[0]})")
    return problems
