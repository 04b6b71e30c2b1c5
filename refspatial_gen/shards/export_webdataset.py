"""Export to WebDataset tar shards (readable by `webdataset.WebDataset`).

One tar member group per sample, keyed by the sample id made safe for file names:
  <key>.rgb<v>.jpg|png   the stored RGB bytes of view v (no re-encoding)
  <key>.depth<v>.npy     float32 metric depth of view v (lossless)
  <key>.json             {sample_id, unit_key, meta, frames (metadata), graphs, qa}
Tars are written with fixed member metadata (mtime 0, uid/gid 0, no user names), so the same shards
give the same tar bytes.
"""

from __future__ import annotations

import io
import json
import tarfile
from pathlib import Path
from typing import Iterable

import numpy as np

from refspatial_gen.core.serialize import dumps
from refspatial_gen.shards.export_refspatial import safe_name
from refspatial_gen.shards.format import RawSample

_EXT = {"jpeg": "jpg", "png": "png"}


def _add(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    ti = tarfile.TarInfo(name)
    ti.size, ti.mtime, ti.mode, ti.uid, ti.gid, ti.uname, ti.gname = len(data), 0, 0o644, 0, 0, "", ""
    tar.addfile(ti, io.BytesIO(data))


def npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(arr), allow_pickle=False)
    return buf.getvalue()


def sample_members(raw: RawSample) -> list[tuple[str, bytes]]:
    h = raw.header
    key = safe_name(h["sample_id"]).replace(".", "_")
    out = []
    for v in range(int(h["views"])):
        data, fmt = raw.image_bytes(v)
        out.append((f"{key}.rgb{v}.{_EXT.get(fmt, fmt)}", data))
        out.append((f"{key}.depth{v}.npy", npy_bytes(raw.depth(v))))
    out.append((f"{key}.json", dumps(raw.meta())))
    return out


def export_webdataset(raws: Iterable[RawSample], out: Path | str, *, samples_per_tar: int = 1000) -> dict:
    """Write `out/wds-00000.tar`, ...; returns {"tars": [names], "samples": n, "bytes": total}."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tars: list[str] = []
    tar = None
    n = 0
    keys: set[str] = set()
    try:
        for raw in raws:
            if n % samples_per_tar == 0:
                if tar is not None:
                    tar.close()
                tars.append(f"wds-{len(tars):05d}.tar")
                tar = tarfile.open(out / tars[-1], "w", format=tarfile.USTAR_FORMAT)
            members = sample_members(raw)
            key = members[0][0].split(".", 1)[0]
            if key in keys:
                raise ValueError(f"two samples map to the WebDataset key {key!r}")
            keys.add(key)
            for name, data in members:
                _add(tar, name, data)
            n += 1
    finally:
        if tar is not None:
            tar.close()
    (out / "manifest.json").write_text(json.dumps({"tars": tars, "samples": n}, sort_keys=True))
    return {"tars": tars, "samples": n, "bytes": sum((out / t).stat().st_size for t in tars)}
