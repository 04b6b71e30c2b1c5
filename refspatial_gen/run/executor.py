"""Executing a plan: shard groups in worker processes (or on Ray), resumable and byte-reproducible.

Crash safety: a group's shard files are written under temporary names and renamed when complete; then a
small group record (`_parts/shard-XXXXX.json`) is written atomically. A group counts as done only when
its record exists and every shard it lists matches its size and sha256. On restart, unfinished groups are
redone from scratch (their units are deterministic), so the result is byte-identical to an uninterrupted
run. `index.json` is written last, atomically.

One run per folder (run/lock.py); the folder's identity covers the input's content (run/outdir.py); a
worker that dies is survived (run/localpool.py); Ctrl-C / SIGTERM stop the workers, discard the groups in
flight and say how to resume; a failed write names its file (core.errors.OutputIOError).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import DropUnit, OutputIOError, RunError, Terminated
from refspatial_gen.core.fsutil import atomic_write_bytes
from refspatial_gen.core.serialize import dumps
from refspatial_gen.recipe import Recipe, load_recipe
from refspatial_gen.run import stats as S
from refspatial_gen.run.faults import FAULT_ENV, fault
from refspatial_gen.run.localpool import marker_path
from refspatial_gen.run.lock import OutputLock
from refspatial_gen.run.outdir import PARTS, discard_groups, group_files, prepare, remove_strays, run_fingerprint
from refspatial_gen.run.pipeline import StageTimer, make_sample
from refspatial_gen.run.plan import Group, Unit, plan_groups, plan_units
from refspatial_gen.run.resume import completed_record


@dataclass(frozen=True)
class RecipeRef:
    """How a worker re-loads the exact recipe (recipes are re-compiled per process, never pickled)."""

    path: str
    seed: int | None
    scenes: int | None
    input_path: str | None
    allow_roots: tuple[str, ...] = ()


@dataclass(frozen=True)
class GroupTask:
    recipe: RecipeRef
    out_dir: str
    group_index: int
    units: tuple[tuple[str, int, str, str], ...]
    strict: bool = False
    skip: tuple[tuple[str, str], ...] = ()  # (unit id, drop reason): units not run (they killed their worker)
    recipe_hash: str = ""  # the plan's recipe hash: a worker refuses a recipe that changed since planning


@lru_cache(maxsize=4)
def _recipe(ref: RecipeRef) -> Recipe:
    return load_recipe(
        ref.path, seed=ref.seed, scenes=ref.scenes, input_path=ref.input_path, allow_roots=ref.allow_roots
    )


def _write_error(e: OSError, fallback: Path) -> OutputIOError:
    return OutputIOError(str(e.filename or fallback), e.strerror or str(e))


def _run_units(
    task: GroupTask, recipe: Recipe, writer: Any, stats: dict, timer: StageTimer, errors: list[dict[str, str]]
) -> None:
    out = Path(task.out_dir)
    skip = dict(task.skip)
    marker = marker_path(out, task.group_index)
    for uid, sidx, kind, key in task.units:
        stats["units"] += 1
        if uid in skip:
            S.add_drop(stats, skip[uid])
            continue
        try:
            marker.write_text(uid, encoding="utf-8")  # names the unit if this process dies (localpool.py)
        except OSError as e:
            raise _write_error(e, marker) from None
        fault("start", uid)
        try:
            sample = make_sample(recipe, Unit(uid, sidx, kind, key), timer, task.out_dir)
        except DropUnit as e:
            S.add_drop(stats, e.reason)
            continue
        except Exception as e:  # a bug or an unforeseen bad input: counted, logged with traceback, never silent
            if task.strict:
                raise
            S.add_drop(stats, f"internal_error:{type(e).__name__}")
            errors.append({"unit": uid, "error": repr(e), "traceback": traceback.format_exc()})
            print(f"refspatial-gen: unit {uid} failed: {e!r} (counted as dropped; see run_log.json)", file=sys.stderr)
            continue
        t = time.perf_counter()
        try:
            writer.write(sample)
        except OSError as e:
            raise _write_error(e, out / f"shard-{task.group_index:05d}.mcap") from None
        timer.add("write", t)
        S.add_sample(stats, sample, kind)
        fault("unit")


def run_group(task: GroupTask) -> dict[str, Any]:
    """Process one shard group; returns its record (deterministic part under "record")."""
    from refspatial_gen.shards.writer import ShardWriter

    recipe = _recipe(task.recipe)
    if task.recipe_hash and recipe.hash != task.recipe_hash:
        _recipe.cache_clear()  # the cache is keyed by path: a file edited between two runs of one process
        recipe = _recipe(task.recipe)
    if task.recipe_hash and recipe.hash != task.recipe_hash:
        raise RunError(
            f"{task.recipe.path} (or a template it names) changed during the run; run the same "
            f"command again to resume with it, or --fresh",
            2,
        )
    out = Path(task.out_dir)
    base = out / f"shard-{task.group_index:05d}.mcap"
    timer = StageTimer()
    stats = S.empty_stats()
    errors: list[dict[str, str]] = []
    try:
        for stale in group_files(out, task.group_index):
            stale.unlink()
        writer = ShardWriter(base, max_bytes=recipe.shards["max_bytes"], image_format=recipe.shards["image_format"])
    except OSError as e:
        raise _write_error(e, base) from None
    _run_units(task, recipe, writer, stats, timer, errors)
    t = time.perf_counter()
    record_path = out / PARTS / f"shard-{task.group_index:05d}.json"
    try:
        infos = [_info_dict(i) for i in writer.finish()]
    except OSError as e:
        raise _write_error(e, base) from None
    timer.add("write", t)
    record = {"group": task.group_index, "units": [u[0] for u in task.units], "shards": infos, "stats": stats}
    try:
        atomic_write_bytes(record_path, dumps(record))
        marker_path(out, task.group_index).unlink(missing_ok=True)
    except OSError as e:
        raise _write_error(e, record_path) from None
    return {
        "record": record,
        "stage_seconds": timer.seconds,
        "peak_rss_mb": peak_rss_mb(),
        "errors": errors,
        "pid": os.getpid(),
    }


def peak_rss_mb() -> float:
    """This process's own peak resident memory. VmHWM, not ru_maxrss: ru_maxrss survives exec, so a spawned
    worker would report its parent's peak."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass  # not Linux: fall back to getrusage below
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _info_dict(info: Any) -> dict[str, Any]:
    if isinstance(info, dict):
        return dict(info)
    if hasattr(info, "to_json"):
        return info.to_json()
    return asdict(info)


def _interrupted(kind: str, code: int, out_dir: Path, done: int, total: int) -> RunError:
    return RunError(
        f"{kind}: {done} of {total} shard groups are finished and kept in {out_dir}; run the same "
        f"command again to resume",
        code,
    )


def run_plan(
    recipe: Recipe,
    ref: RecipeRef,
    out_dir: Path,
    workers: int = 1,
    executor: str = "local",
    ray_address: str | None = None,
    strict: bool = False,
    fresh: bool = False,
    progress: bool = True,
    on_group_done: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Run (or resume) the whole plan into `out_dir`, holding its lock; returns {"index", "stats", "run_log"}.

    Ctrl-C / SIGTERM: workers stopped, groups in flight discarded, RunError (exit 130 / 143) saying how to
    resume."""
    existed = out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputIOError(str(e.filename or out_dir), e.strerror or str(e)) from None
    lock = OutputLock(out_dir)
    lock.acquire()
    started = False
    try:
        units = plan_units(recipe)  # input errors stop here, before the folder is touched
        fingerprint = run_fingerprint(recipe, out_dir)
        started = True
        return _run_locked(
            recipe,
            ref,
            out_dir,
            units,
            fingerprint,
            workers,
            executor,
            ray_address,
            strict,
            fresh,
            progress,
            on_group_done,
        )
    finally:
        lock.release()
        if not started and not existed:  # nothing was planned: leave no folder behind (only we wrote in it)
            shutil.rmtree(out_dir, ignore_errors=True)


def _run_locked(
    recipe: Recipe,
    ref: RecipeRef,
    out_dir: Path,
    units: list[Unit],
    fingerprint: dict[str, Any],
    workers: int,
    executor: str,
    ray_address: str | None,
    strict: bool,
    fresh: bool,
    progress: bool,
    on_group_done: Callable[[int], None] | None,
) -> dict[str, Any]:
    t_start = time.time()
    prepare(out_dir, fingerprint, fresh)
    groups = plan_groups(units, recipe.shards["samples_per_shard"])
    records: dict[int, dict[str, Any]] = {}
    for g in groups:
        rec = completed_record(out_dir, g)
        if rec is not None:
            records[g.index] = rec
    tasks = [
        GroupTask(
            ref,
            str(out_dir),
            g.index,
            tuple((u.uid, u.source_index, u.kind, u.key) for u in g.units),
            strict,
            recipe_hash=recipe.hash,
        )
        for g in groups
        if g.index not in records
    ]
    results: list[dict[str, Any]] = []
    bar = _progress(len(units), sum(len(g.units) for g in groups if g.index in records), progress)
    gen = _execute(tasks, workers, executor, ray_address, out_dir)
    try:
        for res in gen:
            records[res["record"]["group"]] = res["record"]
            results.append(res)
            bar.update(len(res["record"]["units"]))
            bar.set_postfix(qa=sum(r["stats"]["qa_pairs"] for r in records.values()), refresh=False)
            if on_group_done is not None:
                on_group_done(res["record"]["group"])
    except BaseException as e:
        bar.close()
        gen.close()  # stops the workers (the pool's own `finally`) before their files are discarded
        discard_groups(out_dir, [g.index for g in groups if g.index not in records])
        if isinstance(e, KeyboardInterrupt):
            raise _interrupted("interrupted", 130, out_dir, len(records), len(groups)) from None
        if isinstance(e, Terminated):
            raise _interrupted("terminated", 143, out_dir, len(records), len(groups)) from None
        raise
    bar.close()
    return _finish(recipe, out_dir, groups, records, results, fingerprint, workers, executor, t_start)


def _finish(
    recipe: Recipe,
    out_dir: Path,
    groups: list[Group],
    records: dict[int, dict[str, Any]],
    results: list[dict[str, Any]],
    fingerprint: dict[str, Any],
    workers: int,
    executor: str,
    t_start: float,
) -> dict[str, Any]:
    """Merge the group records, remove stray shard files, write index.json (last) and the run log."""
    from refspatial_gen.shards.index import write_index

    total = S.empty_stats()
    shards: list[dict[str, Any]] = []
    for idx in sorted(records):
        total = S.merge(total, records[idx]["stats"])
        for s in records[idx]["shards"]:
            shards.append({**s, "group": idx})
    strays = remove_strays(out_dir, {s["name"] for s in shards}, len(groups))
    if os.environ.get(FAULT_ENV) == "index":  # simulate dying half-way through writing the index
        (out_dir / "index.json.partial").write_bytes(b'{"shards": [')
        fault("index")
    from refspatial_gen.run.splits import index_section

    try:
        index = write_index(out_dir, shards, {**fingerprint, "stats": total, **index_section(recipe, out_dir, shards)})
    except OSError as e:
        raise OutputIOError(str(e.filename or out_dir / "index.json"), e.strerror or str(e)) from None
    wall = time.time() - t_start
    stage = {
        k: round(sum(r["stage_seconds"].get(k, 0.0) for r in results), 3) for k in ("load", "graph", "qa", "write")
    }
    run_log = {
        "wall_seconds": round(wall, 3),
        "stage_seconds": stage,
        "workers": workers,
        "executor": executor,
        "groups_run": len(results),
        "groups_resumed": len(groups) - len(results),
        "units_per_s": round(sum(len(r["record"]["units"]) for r in results) / wall, 3) if wall > 0 else 0.0,
        "qa_per_s": round(sum(r["record"]["stats"]["qa_pairs"] for r in results) / wall, 3) if wall > 0 else 0.0,
        "peak_rss_mb_per_worker": round(max((r["peak_rss_mb"] for r in results), default=0.0), 1),
        "errors": [e for r in results for e in r["errors"]],
        "stray_files_removed": strays,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(t_start)),
        "host": os.uname().nodename,
    }
    try:
        (out_dir / "run_log.json").write_text(json.dumps(run_log, indent=2, sort_keys=True))
    except OSError as e:
        raise OutputIOError(str(out_dir / "run_log.json"), e.strerror or str(e)) from None
    return {"index": index, "stats": total, "run_log": run_log}


def _progress(total: int, initial: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="scene",
        desc="generating",
        disable=not enabled,
        dynamic_ncols=True,
        file=sys.stderr,
    )


def _execute(tasks: list[GroupTask], workers: int, executor: str, ray_address: str | None, out_dir: Path):
    if not tasks:
        return
    if executor == "ray":
        from refspatial_gen.run.ray_executor import execute_on_ray

        yield from execute_on_ray(tasks, workers, ray_address, out_dir)
        return
    if workers <= 1:  # in this process (a native crash here ends the run; resume redoes the group)
        for t in tasks:
            yield run_group(t)
        return
    from refspatial_gen.run.localpool import run_pool

    yield from run_pool(tasks, workers, out_dir, run_group)
