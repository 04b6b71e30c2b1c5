"""CLI: `refspatial-gen recipes lint PATH...` and `refspatial-gen verify DIR [--json]`."""

from __future__ import annotations

import argparse
import json
import sys


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
    from refspatial_gen.tools.lint import lint_paths

    errors = lint_paths(args.paths)
    for e in errors:
        print(str(e))
    if not errors:
        print(f"ok: {len(args.paths)} file(s), no problems")
    return 1 if errors else 0


def _verify(args: argparse.Namespace) -> int:
    from refspatial_gen.tools.verify_dir import verify_dir

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
