#!/usr/bin/env bash
# Byte-identity check for refactors: runs the default, scan (SUN RGB-D, ScanNet) and image recipes and prints
# the sha256 of every shard and index.json. Usage: scripts/output_hashes.sh OUTDIR [REPO] > hashes.txt
# REPO (default: this checkout) lets the same script hash an older commit checked out in a git worktree.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
out="$1"; repo="${2:-$here}"
data="${REFSPATIAL_SHARED_DATA:-$here/../shared/data}"
py="$here/.venv/bin/python"
run() {  # name recipe [extra args]
  local name="$1"; shift
  rm -rf "$out/$name"
  (cd "$repo" && PYTHONPATH="$repo" "$py" -m refspatial_gen.cli shards --recipe "$@" --out "$out/$name" --workers 1 >/dev/null 2>&1)
  (cd "$out/$name" && sha256sum index.json shard-*.mcap | sed "s|  |  $name/|")
}
run default recipes/default.yaml --scenes 12
run sunrgbd recipes/scan.yaml --input "$data/sunrgbd"
run scannet recipes/scan.yaml --input "$data/scannet_scene0000_00"
run coco recipes/image.yaml --input "$data/coco_tiny_train2017"
