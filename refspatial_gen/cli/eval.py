"""`refspatial-gen eval DIR --predictions P.jsonl | --baseline NAME | --audit [--json] [--out report/]`.

Scores model outputs (JSON lines `{"id": <QA id as in export --format jsonl>, "text": <raw output>}`)
against a shard directory: success overall and by family, template, relation, step count, source and
split with 95 % intervals, reward components, parse failures, and every problem of the predictions file.
Exit status: 0; 1 when the predictions file has problems and `--strict` is given, or on bad input.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def register(sub) -> None:
    from refspatial_gen.eval.baselines import BASELINES
    from refspatial_gen.rewards.parse import POINT_CONVENTIONS

    p = sub.add_parser("eval", help="score predictions (or a baseline) on a dataset; shortcut audit (docs/eval.md)")
    p.add_argument("dir", help="shard directory (with index.json)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--predictions", help='JSON lines {"id", "text"}')
    src.add_argument("--baseline", choices=BASELINES, help="score a built-in baseline instead of a model")
    src.add_argument(
        "--audit", action="store_true", help="run the text-only and frequent-choice baselines per template"
    )
    p.add_argument(
        "--split",
        action="append",
        choices=["train", "val", "test", "unseen"],
        help="evaluate only these splits (repeatable; default: all)",
    )
    p.add_argument(
        "--variant",
        choices=["region", "paper"],
        default="region",
        help="answer reward: region (inside the mask, graded outside) or paper (50 px L1 to the gold point)",
    )
    p.add_argument("--point-format", choices=POINT_CONVENTIONS, default="auto", help="how the model writes points")
    p.add_argument("--seed", type=int, default=0, help="seed of the random baseline")
    p.add_argument("--save-predictions", help="with --baseline: also write its predictions as JSON lines")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--out", help="write report.json, index.html and plots to this folder")
    p.add_argument("--strict", action="store_true", help="exit 1 when the predictions file has any problem")
    p.set_defaults(func=cmd_eval)


def _fail(msg: str) -> int:
    print(f"refspatial-gen eval: {msg}", file=sys.stderr)
    return 1


def cmd_eval(args) -> int:
    from refspatial_gen.eval.baselines import audit, predict
    from refspatial_gen.eval.dataset import load_items
    from refspatial_gen.eval.predictions import parse_predictions, read_predictions
    from refspatial_gen.eval.report import write_report
    from refspatial_gen.eval.score import evaluate, summarise

    try:
        items = load_items(Path(args.dir), args.split)
    except (ValueError, OSError) as e:
        return _fail(str(e))
    if not items:
        return _fail(f"{args.dir}: no QA pairs" + (f" in splits {', '.join(args.split)}" if args.split else ""))
    ids = [it.id for it in items]
    audit_rows = None
    if args.audit:
        recs = {
            b: evaluate(items, parse_predictions(_lines(predict(b, items, args.seed)), ids))
            for b in ("text-only", "frequent-choice")
        }
        audit_rows = audit(items, recs)
        preds = parse_predictions(_lines(predict("text-only", items, args.seed)), ids)
        source = "baseline:text-only (audit)"
    elif args.baseline:
        lines = _lines(predict(args.baseline, items, args.seed))
        if args.save_predictions:
            Path(args.save_predictions).write_text("".join(line + "\n" for line in lines))
        preds = parse_predictions(lines, ids)
        source = f"baseline:{args.baseline}"
    else:
        try:
            preds = read_predictions(args.predictions, ids)
        except (ValueError, OSError) as e:
            return _fail(str(e))
        source = args.predictions
    records = evaluate(items, preds, variant=args.variant, point_convention=args.point_format)
    summary = summarise(items, records, preds)
    problems = preds.problem_lines()
    if audit_rows is not None:
        summary["audit"] = audit_rows
    if args.json:
        print(json.dumps(summary, sort_keys=True))
    else:
        _print_text(summary, source, problems, audit_rows)
    if args.out:
        info = {"dataset": str(args.dir), "predictions": source, "variant": args.variant, "splits": args.split}
        path = write_report(Path(args.out), summary, info, problems, audit_rows)
        print(f"report: {path}", file=sys.stderr if args.json else sys.stdout)
    if args.strict and any(preds.problems().values()):
        return _fail(f"{source}: " + ", ".join(f"{k}={v}" for k, v in preds.problems().items() if v))
    return 0


def _lines(preds: dict[str, str]) -> list[str]:
    return [json.dumps({"id": i, "text": t}) for i, t in preds.items()]


def _print_text(s: dict, source: str, problems: list[str], audit_rows: list[dict] | None) -> None:
    p = s["problems"]
    print(
        f"{source}: success {s['success_rate']:.3f} [{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}] over {s['n']} QA pairs; "
        f"reward {s['reward']:.3f}; parse failures {s['parse_failures']}; missing {p['missing_ids']}; unknown ids "
        f"{p['unknown_ids']}; duplicate ids {p['duplicate_ids']}; malformed lines {p['malformed_lines']}"
    )
    comps = ", ".join(f"{k} {v['mean']:.3f} (n={v['n']})" for k, v in s["components"].items() if v["mean"] is not None)
    print(f"  components: {comps}")
    for g in ("family", "steps", "split", "source"):
        rows = s[f"by_{g}"]
        print(
            f"  by {g}: "
            + ", ".join(
                f"{k}={r['success_rate']:.2f} [{r['ci95'][0]:.2f}, {r['ci95'][1]:.2f}] n={r['n']}"
                for k, r in rows.items()
            )
        )
    for line in problems:
        print(f"  {line}")
    if audit_rows:
        print("  shortcut audit (success: text-only / frequent-choice vs chance):")
        for r in audit_rows:
            ch = "  n/a" if r["chance"] is None else f"{r['chance']:.2f}"
            print(
                f"    {r['template']:<40} n={r['n']:<4} chance {ch}  text-only {r['text-only']['success_rate']:.2f}  "
                f"frequent {r['frequent-choice']['success_rate']:.2f}{'  LEAKS' if r['leaks'] else ''}"
            )
