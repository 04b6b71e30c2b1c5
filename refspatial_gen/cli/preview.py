"""`refspatial-gen preview DIR --out D [--n K] [--seed S]`: a browsable gallery of sampled QA pairs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _preview(args: argparse.Namespace) -> int:
    from refspatial_gen.run.preview import preview_dir
    from refspatial_gen.shards.reader import ShardError

    try:
        index = preview_dir(Path(args.dir), Path(args.out), n=args.n, seed=args.seed)
    except (FileNotFoundError, ShardError) as e:
        print(f"refspatial-gen preview: {e}", file=sys.stderr)
        return 1
    print(index)
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "preview",
        help="PNG overlays of sampled QA pairs and an index.html gallery",
        description="Render a seeded sample of QA pairs from the shards under DIR: answer points, "
        "target boxes, free-space regions, question, answer and trace.",
    )
    p.add_argument("dir", help="folder with .mcap shards (searched recursively), or one shard file")
    p.add_argument("--out", required=True, help="output folder for the PNGs and index.html")
    p.add_argument("--n", type=int, default=24, help="number of QA pairs to show (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sample (default 0)")
    p.set_defaults(func=_preview)
