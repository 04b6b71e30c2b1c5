"""Export to Parquet with declared Hugging Face `Features`: `load_dataset`, streaming, Ray Data.

OUT/
  data/train-00000.parquet, ...   one row per sample (shards.records.hf_features): sample_id, images
                                  (stored JPEG/PNG bytes), depth (float32 metres, TIFF), conversations,
                                  typed qa list, meta/frames/graphs as JSON strings
  README.md                       a dataset card whose `dataset_info` declares the features
The features are also in each file's Arrow schema metadata, so `load_dataset("parquet", ...)`,
`load_dataset(OUT)` and `load_dataset(OUT, streaming=True)` all return them typed; `ray.data.read_parquet`
reads the same files. Files hold `samples_per_shard` rows (default as for WebDataset: about 16 files
for a small export, so streaming workers and nodes each get whole files), zstd-compressed, with fixed
writer settings so the same shards give the same bytes.
"""

from __future__ import annotations

import io
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from refspatial_gen.shards.export_files import sha256, stored_image_hashes
from refspatial_gen.shards.export_webdataset import default_samples_per_shard
from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.records import hf_features, sample_record

ROW_GROUP = 16


def depth_tiff(depth: np.ndarray) -> bytes:
    """Metric depth as an uncompressed 32-bit float TIFF (Parquet's zstd compresses the column)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(depth, dtype=np.float32), mode="F").save(buf, format="TIFF")
    return buf.getvalue()


def hf_row(raw: RawSample) -> dict:
    rec = sample_record(raw)
    views = int(raw.header["views"])
    rec["images"] = [{"bytes": raw.image_bytes(v)[0], "path": None} for v in range(views)]
    rec["depth"] = [{"bytes": depth_tiff(raw.depth(v)), "path": None} for v in range(views)]
    return rec


def _write(rows: list[dict], path: Path, features) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(rows, schema=features.arrow_schema)
    pq.write_table(table, path, compression="zstd", row_group_size=ROW_GROUP, write_statistics=False)


def _card(features, n: int, files: list[str], size: int) -> str:
    """A minimal dataset card: YAML `dataset_info` with the features and the data files of the split."""
    import yaml

    info = {
        "configs": [{"config_name": "default", "data_files": [{"split": "train", "path": "data/train-*.parquet"}]}],
        "dataset_info": {
            "features": features._to_yaml_list(),
            "splits": [{"name": "train", "num_examples": n, "num_bytes": size}],
        },
    }
    return (
        "---\n" + yaml.safe_dump(info, sort_keys=True) + "---\n\nExported by refspatial-gen (`export --format hf`): "
        f"{n} samples in {len(files)} Parquet files.\n"
    )


def export_hf(raws: Iterable[RawSample], out: Path | str, *, samples_per_shard: int | None = None) -> dict:
    """Write the Parquet files and the card; returns {"files": [...], "samples": n, "bytes": total}."""
    out = Path(out)
    (out / "data").mkdir(parents=True, exist_ok=True)
    per = int(samples_per_shard or default_samples_per_shard(len(raws) if hasattr(raws, "__len__") else None))
    if per < 1:
        raise ValueError(f"samples_per_shard must be >= 1, got {per}")
    features = hf_features()
    files: list[str] = []
    rows: list[dict] = []
    n = 0
    ids: set[str] = set()
    for raw in raws:
        row = hf_row(raw)
        if row["sample_id"] in ids:
            raise ValueError(f"sample id {row['sample_id']!r} occurs twice")
        ids.add(row["sample_id"])
        rows.append(row)
        n += 1
        if len(rows) == per:
            files.append(f"data/train-{len(files):05d}.parquet")
            _write(rows, out / files[-1], features)
            rows = []
    if rows or not files:
        files.append(f"data/train-{len(files):05d}.parquet")
        _write(rows, out / files[-1], features)
    size = sum((out / f).stat().st_size for f in files)
    (out / "README.md").write_text(_card(features, n, files, size))
    return {"files": files, "samples": n, "bytes": size}


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """Every sample is one row whose images hold the stored bytes and whose depth decodes to the stored
    depth, and the files declare the features (read back with pyarrow, independently of `datasets`)."""
    import pyarrow.parquet as pq

    out = Path(out)
    depth_want: dict[tuple[str, int], str] = {}
    stored = stored_image_hashes(
        raws,
        lambda raw, stem, v: depth_want.__setitem__(
            (raw.header["sample_id"], v), sha256(np.ascontiguousarray(raw.depth(v), "<f4").tobytes())
        ),
    )
    want_rgb = {sv: h for h, sv in stored.values()}
    problems, seen = [], set()
    for f in sorted((out / "data").glob("*.parquet")):
        pf = pq.ParquetFile(f)
        if b"huggingface" not in (pf.schema_arrow.metadata or {}):
            problems.append(f"{f}: no Hugging Face features in the schema metadata")
        for row in pf.read(columns=["sample_id", "images", "depth"]).to_pylist():
            sid = row["sample_id"]
            seen.add(sid)
            for v, img in enumerate(row["images"]):
                if want_rgb.get((sid, v)) != sha256(img["bytes"]):
                    problems.append(f"{f}: images[{v}] of {sid!r} is not the stored image")
            for v, dep in enumerate(row["depth"]):
                arr = _decode_depth(dep["bytes"])
                if depth_want.get((sid, v)) != sha256(arr.astype("<f4").tobytes()):
                    problems.append(f"{f}: depth[{v}] of {sid!r} is not the stored depth")
    missing = {sid for sid, _ in want_rgb} - seen
    if missing:
        problems.append(f"{out}: {len(missing)} samples are not in the Parquet files (e.g. {sorted(missing)[0]!r})")
    return problems


def _decode_depth(data: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)), dtype=np.float32)
