"""CLI: `refspatial-gen export DIR --format ... --out X` and `refspatial-gen inspect SHARD`."""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path


def register(sub) -> None:
    from refspatial_gen.shards.export import EXPORTERS

    p = sub.add_parser(
        "export",
        help="export a shard directory to a trainer's or benchmark's layout: "
        + ", ".join(EXPORTERS)
        + " (docs/shards.md, docs/eval.md)",
        description="Export into a new folder (written beside it, checked, then renamed into place). "
        "Every shard is checked against index.json as it is read.",
    )
    p.add_argument("dir", help="shard directory (with index.json)")
    p.add_argument("--format", required=True, choices=list(EXPORTERS))
    p.add_argument("--out", required=True, help="output folder (must be empty or absent unless --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace a non-empty output folder whole")
    p.add_argument(
        "--samples-per-shard",
        type=int,
        default=None,
        help="webdataset/hf: samples per tar or Parquet file (default: about 16 files, at most 256 each)",
    )
    p.add_argument(
        "--no-check",
        action="store_true",
        help="skip the up-front check of the whole folder (each shard is still verified as it is read)",
    )
    p.add_argument(
        "--split",
        action="append",
        choices=["train", "val", "test", "unseen"],
        help="sft, rft, refspatial-bench: splits to write (repeatable; defaults: train / train / test)",
    )
    p.set_defaults(func=cmd_export)

    q = sub.add_parser("inspect", help="a readable summary of one shard's samples")
    q.add_argument("shard", help="an .mcap shard file")
    q.add_argument("--json", action="store_true", help="print one JSON object per sample")
    q.add_argument("--limit", type=int, default=20, help="samples listed in full (default 20)")
    q.set_defaults(func=cmd_inspect)


def _fail(msg: str) -> int:
    print(f"refspatial-gen: {msg}", file=sys.stderr)
    return 1


def cmd_export(args) -> int:
    from refspatial_gen.shards.export import export
    from refspatial_gen.shards.integrity import check_shards

    if not args.no_check:
        problems = check_shards(Path(args.dir))
        if problems:
            for pr in problems:
                print(f"{pr['file']}: {pr['problem']}: {pr['detail']}", file=sys.stderr)
            return _fail(f"{args.dir}: {len(problems)} integrity problem(s); nothing exported")
    kw = {}
    if args.split:
        if args.format not in ("sft", "rft", "refspatial-bench"):
            return _fail(f"--split applies to the sft, rft and refspatial-bench formats, not {args.format}")
        kw["splits"] = tuple(args.split)
    try:
        res = export(
            Path(args.dir),
            args.format,
            Path(args.out),
            overwrite=args.overwrite,
            samples_per_shard=args.samples_per_shard,
            **kw,
        )
    except (ValueError, OSError) as e:  # ShardError and ExportError are ValueErrors and name the file
        return _fail(str(e))
    except ImportError as e:
        return _fail(
            f"--format {args.format} needs an optional package ({e.name}): pip install 'refspatial-gen[datasets]'"
        )
    print(f"{args.out}: {json.dumps(res, sort_keys=True)}")
    return 0


def cmd_inspect(args) -> int:
    from refspatial_gen.shards.reader import ShardError, iter_raw

    path = Path(args.shard)
    n = n_qa = 0
    fam: Counter = Counter()
    steps: Counter = Counter()
    lines = []
    try:
        for raw in iter_raw(path):
            m = raw.meta()
            n += 1
            n_qa += len(m["qa"])
            fam.update(q["family"] for q in m["qa"])
            steps.update(int(q["steps"]) for q in m["qa"])
            if args.json:
                print(
                    json.dumps(
                        {
                            "sample_id": m["sample_id"],
                            "unit_key": m["unit_key"],
                            "views": len(m["frames"]),
                            "objects": [len(f["objects"]) for f in m["frames"]],
                            "qa_pairs": len(m["qa"]),
                            "families": dict(sorted(Counter(q["family"] for q in m["qa"]).items())),
                        },
                        sort_keys=True,
                    )
                )
            elif n <= args.limit:
                f0 = m["frames"][0]
                cats = Counter(o["category"] for o in f0["objects"])
                lines.append(
                    f"  [{raw.seq}] {m['sample_id']}  source={f0['source']}  views={len(m['frames'])}  "
                    f"{f0['camera']['width']}x{f0['camera']['height']}  objects={len(f0['objects'])} "
                    f"({', '.join(f'{k}={v}' for k, v in sorted(cats.items()))})  qa={len(m['qa'])}"
                )
                for q in m["qa"][:2]:
                    lines.append(
                        f"      {q['family']}/{q['steps']} steps: {q['question'][:90]!r} -> {q['answer'][:40]!r}"
                    )
    except ShardError as e:
        return _fail(str(e))
    if not args.json:
        print(f"{path}: {n} samples, {n_qa} QA pairs, {path.stat().st_size} bytes")
        print("  families: " + ", ".join(f"{k}={v}" for k, v in sorted(fam.items())))
        print("  steps: " + ", ".join(f"{k}={v}" for k, v in sorted(steps.items())))
        print("\n".join(lines))
        if n > args.limit:
            print(f"  ... {n - args.limit} more samples")
    return 0
