"""Executing a plan: shard groups in worker processes (or on Ray), resumable and byte-reproducible.

Crash safety: a group's shard files are written under temporary names and renamed when complete; then a
small group record (`_parts/shard-XXXXX.json`) is written atomically. A group counts as done only when
its record exists and every shard it lists matches its size and sha256. On restart, unfinished groups are
redone from scratch (their units are deterministic), so the result is byte-identical to an uninterrupted
run. `index.json` is written last, atomically.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import sys
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass
from functools import lru_cache
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Callable

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.core.fsutil import atomic_write_bytes, sha256_file
from refspatial_gen.core.serialize import dumps
from refspatial_gen.recipe import Recipe, load_recipe, recipe_fingerprint
from refspatial_gen.run import stats as S
from refspatial_gen.run.pipeline import StageTimer, make_sample
from refspatial_gen.run.plan import Group, Unit, plan_groups, plan_units

PARTS = "_parts"
FAULT_ENV = "REFSPATIAL_FAULT"  # test hook: "unit:N" | "index" — SIGKILL this process at that point
_units_done = 0


def _fault(point: str) -> None:
    """Crash-test hook: kill the process with SIGKILL at a named point when REFSPATIAL_FAULT asks for it."""
    global _units_done
    spec = os.environ.get(FAULT_ENV)
    if not spec:
        return
    if point == "unit":
        _units_done += 1
        if spec == f"unit:{_units_done}":
            os.kill(os.getpid(), signal.SIGKILL)
    elif spec == point:
        os.kill(os.getpid(), signal.SIGKILL)


@dataclass(frozen=True)
class RecipeRef:
    """How a worker re-loads the exact recipe (recipes are re-compiled per process, never pickled)."""

    path: str
    seed: int | None
    scenes: int | None
    input_path: str | None


@dataclass(frozen=True)
class GroupTask:
    recipe: RecipeRef
    out_dir: str
    group_index: int
    units: tuple[tuple[str, int, str, str], ...]
    strict: bool = False


@lru_cache(maxsize=4)
def _recipe(ref: RecipeRef) -> Recipe:
    return load_recipe(ref.path, seed=ref.seed, scenes=ref.scenes, input_path=ref.input_path)


def group_files(out_dir: Path, index: int) -> list[Path]:
    stem = f"shard-{index:05d}"
    return sorted(p for p in out_dir.iterdir() if p.name.startswith(stem + ".") or p.name.startswith(stem + "-"))


def run_group(task: GroupTask) -> dict[str, Any]:
    """Process one shard group; returns its record (deterministic part under "record")."""
    from refspatial_gen.shards.writer import ShardWriter

    recipe = _recipe(task.recipe)
    out = Path(task.out_dir)
    for stale in group_files(out, task.group_index):
        stale.unlink()
    timer = StageTimer()
    stats = S.empty_stats()
    errors: list[dict[str, str]] = []
    writer = ShardWriter(out / f"shard-{task.group_index:05d}.mcap", max_bytes=recipe.shards["max_bytes"],
                         image_format=recipe.shards["image_format"])
    for uid, sidx, kind, key in task.units:
        unit = Unit(uid, sidx, kind, key)
        stats["units"] += 1
        try:
            sample = make_sample(recipe, unit, timer, task.out_dir)
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
        writer.write(sample)
        timer.add("write", t)
        S.add_sample(stats, sample, kind)
        _fault("unit")
    t = time.perf_counter()
    infos = [_info_dict(i) for i in writer.finish()]
    timer.add("write", t)
    record = {"group": task.group_index, "units": [u[0] for u in task.units], "shards": infos, "stats": stats}
    atomic_write_bytes(out / PARTS / f"shard-{task.group_index:05d}.json", dumps(record))
    return {"record": record, "stage_seconds": timer.seconds, "peak_rss_mb": peak_rss_mb(), "errors": errors,
            "pid": os.getpid()}


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


def completed_record(out_dir: Path, group: Group) -> dict[str, Any] | None:
    """The group's record if the group finished and its shards are intact, else None (redo it)."""
    p = out_dir / PARTS / f"{group.name}.json"
    if not p.is_file():
        return None
    try:
        record = json.loads(p.read_bytes())
    except (OSError, ValueError):
        return None
    if record.get("units") != [u.uid for u in group.units]:
        return None
    for s in record.get("shards", []):
        f = out_dir / s["name"]
        if not f.is_file() or f.stat().st_size != s["bytes"] or sha256_file(f) != s["sha256"]:
            return None
    return record


def _check_output_dir(out_dir: Path, fingerprint: dict[str, Any], fresh: bool) -> None:
    marker = out_dir / PARTS / "run.json"
    if marker.is_file():
        old = json.loads(marker.read_bytes())
        if old != fingerprint and not fresh:
            raise SystemExit(
                f"refspatial-gen: {out_dir} holds the output of a different run "
                f"(recipe/seed/scenes/code differ); use another --out or pass --fresh to replace it")
    if fresh and out_dir.exists():
        for p in list(out_dir.glob("shard-*")) + list((out_dir / PARTS).glob("*")) + [out_dir / "index.json"]:
            if p.is_file():
                p.unlink()
    (out_dir / PARTS).mkdir(parents=True, exist_ok=True)
    # leftovers of a killed run: a half-written index or group record (shard partials are redone per group)
    for p in [out_dir / "index.json.partial", *(out_dir / PARTS).glob("*.tmp")]:
        if p.is_file():
            p.unlink()
    atomic_write_bytes(marker, dumps(fingerprint))


def run_plan(recipe: Recipe, ref: RecipeRef, out_dir: Path, workers: int = 1, executor: str = "local",
             ray_address: str | None = None, strict: bool = False, fresh: bool = False,
             progress: bool = True, on_group_done: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Run (or resume) the whole plan into `out_dir`; returns {"index": ..., "run_log": ...}."""
    from refspatial_gen.shards.index import write_index

    t_start = time.time()
    out_dir.mkdir(parents=True, exist_ok=True)
    fingerprint = recipe_fingerprint(recipe)
    _check_output_dir(out_dir, fingerprint, fresh)
    units = plan_units(recipe)
    groups = plan_groups(units, recipe.shards["samples_per_shard"])
    records: dict[int, dict[str, Any]] = {}
    for g in groups:
        rec = completed_record(out_dir, g)
        if rec is not None:
            records[g.index] = rec
    todo = [g for g in groups if g.index not in records]
    tasks = [GroupTask(ref, str(out_dir), g.index, tuple((u.uid, u.source_index, u.kind, u.key) for u in g.units), strict)
             for g in todo]
    results: list[dict[str, Any]] = []
    bar = _progress(len(units), sum(len(g.units) for g in groups if g.index in records), progress)
    for res in _execute(tasks, workers, executor, ray_address):
        records[res["record"]["group"]] = res["record"]
        results.append(res)
        bar.update(len(res["record"]["units"]))
        bar.set_postfix(qa=sum(r["stats"]["qa_pairs"] for r in records.values()), refresh=False)
        if on_group_done is not None:
            on_group_done(res["record"]["group"])
    bar.close()
    total = S.empty_stats()
    shards: list[dict[str, Any]] = []
    for idx in sorted(records):
        total = S.merge(total, records[idx]["stats"])
        for s in records[idx]["shards"]:
            shards.append({**s, "group": idx})
    if os.environ.get(FAULT_ENV) == "index":  # simulate dying half-way through writing the index
        (out_dir / "index.json.partial").write_bytes(b'{"shards": [')
        _fault("index")
    from refspatial_gen.run.splits import index_section

    index = write_index(out_dir, shards, {**fingerprint, "stats": total, **index_section(recipe, out_dir, shards)})
    wall = time.time() - t_start
    stage = {k: round(sum(r["stage_seconds"].get(k, 0.0) for r in results), 3) for k in ("load", "graph", "qa", "write")}
    run_log = {
        "wall_seconds": round(wall, 3), "stage_seconds": stage, "workers": workers, "executor": executor,
        "groups_run": len(results), "groups_resumed": len(groups) - len(results),
        "units_per_s": round(sum(len(r["record"]["units"]) for r in results) / wall, 3) if wall > 0 else 0.0,
        "qa_per_s": round(sum(r["record"]["stats"]["qa_pairs"] for r in results) / wall, 3) if wall > 0 else 0.0,
        "peak_rss_mb_per_worker": round(max((r["peak_rss_mb"] for r in results), default=0.0), 1),
        "errors": [e for r in results for e in r["errors"]],
        "started": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(t_start)), "host": os.uname().nodename,
    }
    (out_dir / "run_log.json").write_text(json.dumps(run_log, indent=2, sort_keys=True))
    return {"index": index, "stats": total, "run_log": run_log}


def _progress(total: int, initial: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="scene", desc="generating", disable=not enabled,
                dynamic_ncols=True, file=sys.stderr)


def _execute(tasks: list[GroupTask], workers: int, executor: str, ray_address: str | None):
    if not tasks:
        return
    if executor == "ray":
        from refspatial_gen.run.ray_executor import execute_on_ray

        yield from execute_on_ray(tasks, workers, ray_address)
        return
    if workers <= 1:
        for t in tasks:
            yield run_group(t)
        return
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        pending = {pool.submit(run_group, t) for t in tasks[: workers * 2]}
        queue = list(tasks[workers * 2 :])
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in sorted(done, key=id):
                yield fut.result()
                if queue:
                    pending.add(pool.submit(run_group, queue.pop(0)))
