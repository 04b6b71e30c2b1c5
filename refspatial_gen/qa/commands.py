"""CLI: `refspatial-gen recipes lint PATH...` and `refspatial-gen verify DIR [--json]`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def register(sub) -> None:
    r = sub.add_parser("recipes", help="recipe and template tools")
    rs = r.add_subparsers(dest="recipes_command", required=True)
    lint = rs.add_parser("lint", help="check recipes and template files; report file:line: message")
    lint.add_argument("paths", nargs="+")
    lint.set_defaults(func=_lint)
    v = sub.add_parser("verify", help="re-check every QA pair of a shard directory on an independent code path")
    v.add_argument("dir", help="shard directory (with index.json)")
    v.add_argument("--json", action="store_true", help="print {qa_pairs, passed, failed, failures} as JSON")
    v.add_argument("--max-failures", type=int, default=1000, help="failures listed at most (all are counted)")
    v.set_defaults(func=_verify)


def _lint(args: argparse.Namespace) -> int:
    from refspatial_gen.qa.lint import lint_paths

    errors = lint_paths(args.paths)
    for e in errors:
        print(str(e))
    if not errors:
        print(f"ok: {len(args.paths)} file(s), no problems")
    return 1 if errors else 0


def iter_dir_samples(d: str | Path):
    """Every sample of every shard listed in DIR/index.json, in index order."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import read_samples

    d = Path(d)
    index = read_index(d)
    for row in index["shards"]:
        yield from read_samples(d / row["name"])


def verify_dir(d: str | Path, max_failures: int = 1000) -> dict:
    """Shard integrity (size and sha256 against index.json) first, then every QA pair.

    A shard with an integrity problem is reported and its samples are not read (they cannot be trusted)."""
    from refspatial_gen.qa.verify import verify_samples
    from refspatial_gen.shards.integrity import check_shards

    problems = check_shards(Path(d))
    bad = {Path(p["file"]).name for p in problems}
    out = verify_samples(_iter_trusted(d, bad))
    out["shard_problems"] = problems
    out["failures"] = out["failures"][:max_failures]
    return out


def _iter_trusted(d: str | Path, skip: set[str]):
    """Samples of every shard in index.json except those named in `skip`, which are never opened (a corrupt
    chunk would stop the reader before the report is written)."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import read_samples

    d = Path(d)
    for row in read_index(d)["shards"]:
        if row["name"] not in skip and (d / row["name"]).is_file():
            yield from read_samples(d / row["name"])


def _verify(args: argparse.Namespace) -> int:
    try:
        res = verify_dir(args.dir, args.max_failures)
    except ValueError as e:
        print(f"verify: {e}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(res, indent=1, sort_keys=True))
    else:
        for p in res["shard_problems"]:
            print(f"{p['file']}: {p['problem']}: {p.get('detail', '')}")
        for f in res["failures"]:
            print(f"{f['sample_id']} {f['qa_id']} [{f['template']}]: {f['reason']}")
        pct = 100.0 * res["passed"] / res["qa_pairs"] if res["qa_pairs"] else 100.0
        print(f"{res['passed']}/{res['qa_pairs']} QA pairs pass ({pct:.2f}%), {res['failed']} fail")
    return 0 if res["failed"] == 0 and not res["shard_problems"] else 1
