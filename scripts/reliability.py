#!/usr/bin/env python3
"""Rebuild and rerun the reliability cases: broken scene inputs and mutated recipes.

    .venv/bin/python scripts/reliability.py [--data ../shared/data] [--only inputs|recipes] [--write-doc]

Each case runs the real command line in this process on a temporary folder (see scripts/relrun.py) and
must end in a `file:line` / `path:` error (exit 2, nothing written) or a counted drop with a named
reason; never a traceback, a hang, silent acceptance or the contents of a file the recipe must not read.
With --write-doc the table in docs/reliability.md is replaced. Exit status 1 when any case fails.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from relcases_inputs import input_cases  # noqa: E402
from relcases_recipes import recipe_cases  # noqa: E402
from relrun import REPO, Outcome, classify  # noqa: E402

DOC = REPO / "docs" / "reliability.md"
BEGIN, END = "<!-- cases:begin -->", "<!-- cases:end -->"


def run_all(data: Path, only: str | None, match: str | None, verbose: bool) -> list[Outcome]:
    os.environ.setdefault("MUJOCO_GL", "egl")
    factories = []
    if only in (None, "inputs"):
        factories += [f(data) for f in input_cases()]
    if only in (None, "recipes"):
        factories += recipe_cases()
    results = []
    for case in factories:
        if match and match not in f"{case.group} {case.name}":
            continue
        with tempfile.TemporaryDirectory(prefix="relcase-") as tmp:
            res = classify(case, Path(tmp))
        results.append(res)
        if verbose:
            flag = "ok  " if res.ok else "FAIL"
            print(f"{flag} {res.seconds:6.1f}s  [{case.group}] {case.name}: {res.summary}", flush=True)
    return results


def _cell(text: str, limit: int = 90) -> str:
    text = text.replace("|", "\\|").replace("\n", " ")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def table(results: list[Outcome]) -> str:
    rows = ["| # | group | case | expected | outcome |", "|---|---|---|---|---|"]
    for i, r in enumerate(results, 1):
        mark = "" if r.ok else "**FAIL** "
        rows.append(f"| {i} | {r.case.group} | {_cell(r.case.name)} | {r.case.expect} | {mark}{_cell(r.summary, 160)} |")
    return "\n".join(rows)


def write_doc(results: list[Outcome]) -> None:
    text = DOC.read_text()
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    inputs = [r for r in results if r.case.group not in RECIPE_GROUPS]
    hand = [r for r in results if r.case.group in RECIPE_GROUPS and r.case.group != "mutation"]
    generated = [r for r in results if r.case.group == "mutation"]
    body = (f"\n### Broken scene inputs\n\n{summary_line(inputs, 'broken inputs')}\n\n{table(inputs)}\n\n"
            f"### Hostile and broken recipes\n\n{summary_line(hand + generated, 'recipe mutations')} "
            f"Hand-written cases first; then every key of every shipped recipe given a wrong type, NaN, an unknown "
            f"sibling, a misspelling, or deleted when required.\n\n{table(hand)}\n\n"
            f"<details><summary>{len(generated)} generated mutations of the shipped recipes</summary>\n\n"
            f"{table(generated)}\n\n</details>\n")
    DOC.write_text(head + BEGIN + body + END + tail)


def summary_line(results: list[Outcome], what: str) -> str:
    n_err = sum(r.ok and r.summary.startswith("error") for r in results)
    n_drop = sum(r.ok and r.summary.startswith("drop") for r in results)
    n_ok = sum(r.ok and r.summary.startswith("ok") for r in results)  # valid variants and recipe baselines
    bad = sum(not r.ok for r in results)
    return (f"**{len(results)} {what}**: {n_err} refused with a `file:line` / `path:` error, {n_drop} dropped with a "
            f"counted reason, {n_ok} accepted as valid, {bad} failed.")


RECIPE_GROUPS = ("recipe", "yaml", "paths", "overrides", "mutation")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default=os.environ.get("REFSPATIAL_SHARED_DATA", str(REPO.parent / "shared" / "data")))
    ap.add_argument("--only", choices=["inputs", "recipes"])
    ap.add_argument("-k", dest="match", help="only cases whose group or name contains this")
    ap.add_argument("--write-doc", action="store_true", help=f"replace the case tables in {DOC.relative_to(REPO)}")
    ap.add_argument("-q", "--quiet", action="store_true")
    args = ap.parse_args()
    data = Path(args.data)
    if args.only != "recipes" and not data.is_dir():
        print(f"{data}: shared sample data not found (--data or REFSPATIAL_SHARED_DATA)", file=sys.stderr)
        return 2
    results = run_all(data, args.only, args.match, not args.quiet)
    print(summary_line(results, "cases"))
    if args.write_doc:
        write_doc(results)
        print(f"wrote {DOC}")
    return 0 if all(r.ok for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
