"""CLI: `refspatial-gen audit DIR... --n K --out D`, `audit serve D`, `audit mark D ITEM VERDICT`, `audit summary D`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

SUBCOMMANDS = ("serve", "mark", "summary")


def register(sub) -> None:
    p = sub.add_parser(
        "audit",
        help="judge a stratified sample of QA pairs by eye; rates with 95%% intervals",
        description="`audit [LABEL=]DIR... --out D`: pick a stratified sample (dataset x family x "
        "steps) and write a review page. `audit serve D`: open it with verdicts saved to "
        "D/verdicts.jsonl. `audit mark D ITEM right|wrong|ambiguous [--note]`: record one "
        "verdict. `audit summary D [--json|--markdown]`: rates per stratum.",
    )
    p.add_argument(
        "args", nargs="+", metavar="ARG", help="dataset folders ([LABEL=]DIR), or a subcommand and its arguments"
    )
    p.add_argument("--out", help="audit folder to write (for a new audit)")
    p.add_argument("--n", type=int, default=150, help="QA pairs to sample (default 150)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--min-per-dataset",
        type=int,
        default=30,
        dest="min_per",
        help="at least this many from each dataset (default 30)",
    )
    p.add_argument("--port", type=int, default=8765, help="serve: port on 127.0.0.1 (default 8765)")
    p.add_argument("--note", default="", help="mark: what is wrong or unclear")
    p.add_argument("--json", action="store_true", help="summary: machine-readable")
    p.add_argument("--markdown", action="store_true", help="summary: Markdown tables for docs/quality.md")
    p.set_defaults(func=cmd_audit)


def _fail(msg: str) -> int:
    print(f"refspatial-gen audit: {msg}", file=sys.stderr)
    return 2


def cmd_audit(args: argparse.Namespace) -> int:
    head, rest = args.args[0], args.args[1:]
    try:
        if head == "serve":
            return _serve(rest, args.port)
        if head == "mark":
            return _mark(rest, args.note)
        if head == "summary":
            return _summary(rest, args.json, args.markdown)
        return _build(args)
    except (ValueError, FileNotFoundError, OSError) as e:
        return _fail(str(e))


def _build(args: argparse.Namespace) -> int:
    from refspatial_gen.audit.page import build_audit

    if not args.out:
        return _fail("give --out D for a new audit (or one of: " + ", ".join(SUBCOMMANDS) + ")")
    if args.n < 1 or args.min_per < 0:
        return _fail("--n must be >= 1 and --min-per-dataset >= 0")
    index = build_audit(args.args, Path(args.out), n=args.n, seed=args.seed, min_per_label=args.min_per)
    print(f"{index}\nreview it with: refspatial-gen audit serve {args.out}")
    return 0


def _serve(rest: list[str], port: int) -> int:
    from refspatial_gen.audit.serve import make_server
    from refspatial_gen.audit.verdicts import read_items

    if len(rest) != 1:
        return _fail("usage: audit serve D [--port P]")
    read_items(Path(rest[0]))  # a clear error for a folder that is not an audit
    server = make_server(Path(rest[0]), port)
    print(f"reviewing {rest[0]} at http://127.0.0.1:{server.server_address[1]}/index.html (Ctrl-C to stop)")
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        print("stopped; verdicts are in verdicts.jsonl")
    finally:
        server.server_close()
    return 0


def _mark(rest: list[str], note: str) -> int:
    from refspatial_gen.audit.verdicts import Verdict, append_verdict

    if len(rest) != 3:
        return _fail("usage: audit mark D ITEM_ID right|wrong|ambiguous [--note TEXT]")
    append_verdict(Path(rest[0]), Verdict(rest[1], rest[2], note))
    return 0


def _summary(rest: list[str], as_json: bool, as_markdown: bool) -> int:
    from refspatial_gen.audit.verdicts import summarise, summary_markdown

    if len(rest) != 1:
        return _fail("usage: audit summary D [--json|--markdown]")
    s = summarise(Path(rest[0]))
    if as_json:
        print(json.dumps(s, indent=1, sort_keys=True, ensure_ascii=False))
    elif as_markdown:
        print(summary_markdown(s), end="")
    else:
        o = s["overall"]
        print(f"{s['items']} items, {o['judged']} judged, {s['unjudged']} unjudged")
        for word in ("right", "wrong", "ambiguous"):
            r = o[word]
            if r["rate"] is not None:
                print(
                    f"  {word:9s} {r['count']:4d}  {100 * r['rate']:5.1f}%  (95% CI {100 * r['ci95'][0]:.1f}–"
                    f"{100 * r['ci95'][1]:.1f}%)"
                )
        for p in s["problems"]:
            print(f"  {p['verdict']:9s} {p['item_id']}: {p['note']}")
    return 0
