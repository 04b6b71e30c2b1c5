"""CLI: `shards` (generate, resume, salvage) and `stats`."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "shards",
        help="generate a dataset from a recipe (resumes an interrupted run)",
        description="Generate shards from a recipe. Running it again on the same --out resumes: "
        "finished shards are verified by hash and kept, unfinished ones are redone. "
        "`shards salvage FILE` recovers the complete samples of an unfinished shard.",
    )
    p.add_argument("action", nargs="?", choices=["run", "salvage"], default="run")
    p.add_argument("paths", nargs="*", help="with `salvage`: unfinished shard files (*.partial)")
    p.add_argument("--recipe", default="recipes/default.yaml")
    p.add_argument("--out", default=None, help="output folder (default out/shards/<recipe name>)")
    p.add_argument("--scenes", type=int, default=None, help="override the recipe's scene count")
    p.add_argument("--seed", type=int, default=None, help="override the recipe's seed")
    p.add_argument("--input", default=None, help="input folder for scan/image sources")
    p.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 1)), help="worker processes")
    p.add_argument("--executor", choices=["local", "ray"], default="local")
    p.add_argument("--ray-address", default=None, help="Ray cluster address (default: start a local instance)")
    p.add_argument("--fresh", action="store_true", help="discard a previous run's output in --out")
    p.add_argument("--strict", action="store_true", help="stop on an internal error instead of counting it")
    p.add_argument(
        "--allow-root",
        action="append",
        default=[],
        metavar="DIR",
        help="also allow the recipe to read files under DIR (repeatable; see docs/reliability.md)",
    )
    p.add_argument("--no-report", action="store_true", help="skip the HTML run report")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_shards)

    s = sub.add_parser("stats", help="dataset statistics of a shard folder")
    s.add_argument("dir")
    s.add_argument("--json", action="store_true")
    s.add_argument(
        "--no-check", action="store_true", help="skip the size/sha256 check of the shards against index.json"
    )
    s.set_defaults(func=cmd_stats)


OUT_ROOT = Path("out/shards")


def _out_dir(args, recipe) -> Path:
    """--out as given; else out/shards/<recipe name>, which must stay under out/shards."""
    from refspatial_gen.core.errors import RecipeError
    from refspatial_gen.recipe_paths import check_name, is_under

    if args.out:
        return Path(args.out)
    msg = check_name(recipe.name)
    out = OUT_ROOT / recipe.name
    if msg or not is_under(out.resolve(), OUT_ROOT.resolve()) or out.resolve() == OUT_ROOT.resolve():
        raise RecipeError(recipe.path, 1, f"name: {msg or 'must name a folder under out/shards'} (or give --out)")
    return out


def _resolve(path: str, flag: str) -> str:
    """An absolute path for a command-line folder; a symlink loop is an error, not a traceback."""
    from refspatial_gen.core.errors import InputError

    try:
        return str(Path(path).resolve())
    except (OSError, RuntimeError) as e:
        raise InputError(path, f"{flag}: cannot be resolved ({type(e).__name__}: {e})") from None


def _check_args(args) -> None:
    from refspatial_gen.core.errors import RecipeErrors
    from refspatial_gen.recipe import OverrideError

    errors = []
    if args.workers < 1:
        errors.append(OverrideError("--workers", None, f"must be >= 1, got {args.workers}"))
    if args.input is not None and not args.input.strip():
        errors.append(OverrideError("--input", None, "must name a folder, got an empty string"))
    if errors:
        raise RecipeErrors(errors)


def cmd_shards(args) -> int:
    if args.action == "salvage":
        return _salvage(args.paths)
    from refspatial_gen.recipe import load_recipe
    from refspatial_gen.run.executor import RecipeRef, run_plan

    _check_args(args)
    inp = None if args.input is None else _resolve(args.input, "--input")
    allow = tuple(_resolve(a, "--allow-root") for a in args.allow_root)
    recipe = load_recipe(args.recipe, seed=args.seed, scenes=args.scenes, input_path=inp, allow_roots=allow)
    out = _out_dir(args, recipe)
    ref = RecipeRef(str(Path(args.recipe).resolve()), args.seed, args.scenes, inp, allow)
    result = run_plan(
        recipe,
        ref,
        out,
        workers=args.workers,
        executor=args.executor,
        ray_address=args.ray_address,
        strict=args.strict,
        fresh=args.fresh,
        progress=not args.quiet,
    )
    st, log = result["stats"], result["run_log"]
    if not args.no_report:
        from refspatial_gen.run.report import write_report

        info = {k: v for k, v in result["index"].items() if k not in ("shards", "stats")}
        info["families"] = {f.name: f.weight for f in recipe.qa.families}
        report = write_report(out, st, log, info)
        print(f"report: {report}")
    dropped = sum(st["dropped"].values())
    print(
        f"{out}: {st['samples']} samples, {st['qa_pairs']} QA pairs in {len(result['index']['shards'])} shards; "
        f"{dropped} of {st['units']} units dropped {st['dropped'] or ''}; "
        f"{log['wall_seconds']:.1f} s, {log['qa_per_s']:.1f} QA/s"
    )
    from refspatial_gen.run.report import silent_families

    silent = silent_families(st, {"families": {f.name: f.weight for f in recipe.qa.families}})
    if silent:
        print(f"warning: families that produced no QA pair: {', '.join(silent)} (see the report)", file=sys.stderr)
    if log["errors"]:
        print(
            f"warning: {len(log['errors'])} units failed with internal errors; tracebacks in {out / 'run_log.json'}",
            file=sys.stderr,
        )
    if st["units"] and not st["samples"]:
        top = sorted(st["dropped"].items(), key=lambda kv: (-kv[1], kv[0]))[:5]
        print(
            f"refspatial-gen: every unit was dropped; top reasons: {', '.join(f'{k} ({v})' for k, v in top)}",
            file=sys.stderr,
        )
        return 1
    return 0


def _salvage(paths: list[str]) -> int:
    from refspatial_gen.shards.integrity import salvage_shard

    if not paths:
        print("shards salvage: give the unfinished shard files", file=sys.stderr)
        return 2
    rc = 0
    for p in paths:
        try:
            info = salvage_shard(Path(p))
        except (OSError, ValueError) as e:
            print(f"{p}: cannot salvage: {e}", file=sys.stderr)
            rc = 1
            continue
        print(f"{p}: {json.dumps(info, sort_keys=True)}")
    return rc


def cmd_stats(args) -> int:
    """Statistics recorded in index.json, after checking that the shards they describe are intact."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.integrity import check_shards

    try:
        index = read_index(Path(args.dir))
    except ValueError as e:
        print(f"stats: {e}", file=sys.stderr)
        return 2
    problems = [] if args.no_check else check_shards(Path(args.dir))
    if problems:
        for pr in problems:
            print(f"{pr['file']}: {pr['problem']}: {pr['detail']}", file=sys.stderr)
        print(
            f"stats: {args.dir}: {len(problems)} integrity problem(s); the statistics would not describe "
            f"the shards on disk (--no-check shows them anyway)",
            file=sys.stderr,
        )
        return 1
    st = index.get("stats")
    keys = ("samples", "qa_pairs", "by_relation", "by_family", "by_steps", "by_source", "dropped")
    if not isinstance(st, dict) or any(not isinstance(st.get(k), (int, dict)) for k in keys):
        print(f"stats: {Path(args.dir) / 'index.json'}: no run statistics (not written by `shards`?)", file=sys.stderr)
        return 2
    out = {k: st[k] for k in keys}
    out["truth"] = st.get("truth", {})
    out["units"] = st.get("units", 0)
    out["shards"] = len(index["shards"])
    if args.json:
        print(json.dumps(out, indent=2, sort_keys=True))
        return 0
    print(
        f"{args.dir}: {out['samples']} samples, {out['qa_pairs']} QA pairs, {out['shards']} shards, "
        f"{sum(out['dropped'].values())} of {out['units']} units dropped"
    )
    for key in ("by_family", "by_steps", "by_source", "by_relation", "dropped", "truth"):
        items = sorted(out[key].items(), key=lambda kv: (-kv[1], kv[0]))
        print(f"  {key}: " + ", ".join(f"{k}={v}" for k, v in items))
    return 0
