"""Shards: MCAP files of Samples (Foxglove-viewable), their index, integrity checks, salvage and exports.

Public API (see docs/shards.md):
  ShardWriter(final_path, max_bytes=None, image_format="jpeg").write(sample) ... .finish() -> [ShardInfo]
  read_samples(path) -> Iterator[Sample];  read_sample_meta(path) -> Iterator[dict]
  write_index(out_dir, shards, run_info);  read_index(out_dir) -> dict
  check_shards(out_dir) -> [problem dicts];  salvage_shard(partial_path) -> dict
"""

from refspatial_gen.shards.index import read_index, shard_paths, write_index
from refspatial_gen.shards.reader import ShardError, iter_raw, read_sample_meta, read_samples
from refspatial_gen.shards.writer import PARTIAL_SUFFIX, ShardInfo, ShardWriter, part_name, sha256_file

__all__ = [
    "PARTIAL_SUFFIX",
    "ShardError",
    "ShardInfo",
    "ShardWriter",
    "iter_raw",
    "part_name",
    "read_index",
    "read_sample_meta",
    "read_samples",
    "sha256_file",
    "shard_paths",
    "write_index",
]
