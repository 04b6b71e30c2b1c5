"""CLI: `refspatial-gen rewrite DIR --out DIR2` (LLM rewording of a finished dataset) and
`refspatial-gen language DIR` (how varied its questions are)."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace


def register(sub) -> None:
    r = sub.add_parser(
        "rewrite",
        help="reword a dataset's questions with an LLM server, each rewrite checked",
        description="Rewrite the questions of a finished shard folder through an OpenAI-compatible "
        "server. Every rewrite is checked; failures keep the original and are counted. "
        "Replies are cached, so a rerun or resume sends no request twice.",
    )
    r.add_argument("dir", help="source shard folder (with index.json)")
    r.add_argument("--out", required=True, help="output shard folder")
    r.add_argument(
        "--config",
        default="recipes/rewrite/local.yaml",
        help="a recipe or file with a `rewrite:` section (default recipes/rewrite/local.yaml)",
    )
    r.add_argument("--server", default=None, help="override the server base URL (.../v1)")
    r.add_argument("--model", default=None, help="override the model id")
    r.add_argument("--cache", default=None, help="reply cache folder (default OUT/rewrite_cache)")
    r.add_argument("--concurrency", type=int, default=None, help="requests in flight")
    r.add_argument("--quiet", action="store_true")
    r.set_defaults(func=_rewrite)
    lang = sub.add_parser("language", help="distinct-question share (phrases and numbers masked, format dropped)")
    lang.add_argument("dir", help="shard folder (with index.json)")
    lang.add_argument("--categories", action="store_true", help="also mask bare category words (stricter)")
    lang.add_argument("--top", type=int, default=10, help="most repeated wordings listed")
    lang.add_argument("--json", action="store_true")
    lang.set_defaults(func=_language)


def _rewrite(args: argparse.Namespace) -> int:
    from refspatial_gen.rewrite.config import load_rewrite_file
    from refspatial_gen.rewrite.dataset import accepted_share, rewrite_dir

    cfg = load_rewrite_file(args.config)
    if cfg is None:
        print(f"rewrite: {args.config} has `enabled: false`", file=sys.stderr)
        return 2
    over = {
        k: v
        for k, v in (("server", args.server), ("model", args.model), ("concurrency", args.concurrency))
        if v is not None
    }
    cfg = replace(cfg, **over)

    def progress(name, c) -> None:
        if not args.quiet:
            print(f"{name}: " + ", ".join(f"{k}={v}" for k, v in sorted(c.items())), file=sys.stderr)

    try:
        res = rewrite_dir(args.dir, args.out, cfg, cache_dir=args.cache, progress=progress)
    except ValueError as e:
        print(f"rewrite: {e}", file=sys.stderr)
        return 2
    c = res["counts"]
    print(
        f"{args.out}: {sum(c.values())} pairs sent, {c.get('accepted', 0)} rewrites kept "
        f"({100 * accepted_share(c):.1f}%); kept originals by reason: "
        + (", ".join(f"{k}={v}" for k, v in c.items() if k != "accepted") or "none")
    )
    return 0


def _language(args: argparse.Namespace) -> int:
    from refspatial_gen.rewrite.language import language_stats

    try:
        st = language_stats(args.dir, categories=args.categories, top=args.top)
    except ValueError as e:
        print(f"language: {e}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(st, indent=1, sort_keys=True))
        return 0
    print(
        f"{args.dir}: {st['distinct']} distinct of {st['questions']} questions = {100 * st['share']:.1f}% "
        f"(masked: {st['masked']}, numbers; format suffix dropped); {st['rewritten']} rewritten by a model"
    )
    for fam, f in st["by_family"].items():
        print(f"  {fam:14s} {f['distinct']:5d} / {f['questions']:5d} = {100 * f['share']:.1f}%")
    for n, w in st["most_repeated"]:
        print(f"  {n:4d} x {w}")
    return 0
