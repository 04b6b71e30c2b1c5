"""The local worker pool: shard groups in spawned processes, surviving a worker that dies.

Why not a bare ProcessPoolExecutor: one worker killed (out of memory, a segfault in a native library)
breaks the whole pool (`BrokenProcessPool`) and the run with it. Here the groups that were in flight when
the pool broke are set aside and, once the others are done, run again one at a time in a fresh
one-worker pool, where a crash can be pinned on one unit: each worker names the unit it is working on in
`_parts/shard-XXXXX.unit`. A unit that kills its worker `MAX_UNIT_CRASHES` times when run alone is then
dropped with the reason `worker_crashed` and its group finished without it.

Workers ignore SIGINT (Ctrl-C reaches the whole process group; the parent decides), and die with their
parent: PR_SET_PDEATHSIG on Linux, plus a thread that exits when the parent pid changes. On any exit of
the parent's loop (an interrupt included) the workers are terminated, not waited for.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RunError

MAX_UNIT_CRASHES = 2
UNIT_MARKER = "shard-{index:05d}.unit"
_PR_SET_PDEATHSIG = 1


def marker_path(out_dir: Path, index: int) -> Path:
    return Path(out_dir) / "_parts" / UNIT_MARKER.format(index=index)


def read_marker(out_dir: Path, index: int) -> str | None:
    try:
        uid = marker_path(out_dir, index).read_text(encoding="utf-8").strip()
    except OSError:
        return None
    return uid or None


def _watch_parent(ppid: int) -> None:
    while True:
        if os.getppid() != ppid:
            os._exit(1)
        time.sleep(0.5)


def worker_init(ppid: int) -> None:
    """Runs first in every worker: ignore Ctrl-C, die with the parent."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass  # the watcher thread below still applies
    if os.getppid() != ppid:
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(ppid,), daemon=True, name="parent-watch").start()


def _new_pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(
        max_workers=workers, mp_context=get_context("spawn"), initializer=worker_init, initargs=(os.getpid(),)
    )


def stop_pool(pool: ProcessPoolExecutor) -> None:
    """Terminate the workers now (an interrupted or failed run must not leave them writing)."""
    procs = list(getattr(pool, "_processes", {}).values())
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(timeout=5)
        if p.is_alive():
            p.kill()
            p.join(timeout=5)
    pool.shutdown(wait=False, cancel_futures=True)


def run_pool(tasks: list, workers: int, out_dir: Path, run_group: Callable[[Any], dict]) -> Iterator[dict]:
    """Yield each task's result (any order). Tasks are GroupTask-like: `.group_index`, `.skip`."""
    queue: deque = deque(tasks)
    suspects: list = []
    while queue:
        pool = _new_pool(workers)
        inflight: dict[Future, Any] = {}
        try:
            while queue or inflight:
                while queue and len(inflight) < workers * 2:
                    t = queue.popleft()
                    inflight[pool.submit(run_group, t)] = t
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                broken = False
                for fut in sorted(done, key=lambda f: inflight[f].group_index):
                    task = inflight.pop(fut)
                    try:
                        res = fut.result()
                    except BrokenProcessPool:
                        suspects.append(task)
                        broken = True
                        continue
                    yield res
                if broken:
                    suspects.extend(inflight.values())  # the pool is gone: its other groups are suspects too
                    inflight.clear()
                    break
        finally:
            stop_pool(pool)
    for task in sorted(suspects, key=lambda t: t.group_index):
        yield run_isolated(task, out_dir, run_group)


def run_isolated(task: Any, out_dir: Path, run_group: Callable[[Any], dict]) -> dict:
    """Run one group alone; a worker death is blamed on the unit it named, dropped after MAX_UNIT_CRASHES."""
    crashes: Counter = Counter()
    while True:
        pool = _new_pool(1)
        try:
            return pool.submit(run_group, task).result()
        except BrokenProcessPool:
            uid = read_marker(out_dir, task.group_index)
            if uid is None:
                raise RunError(
                    f"shard group {task.group_index}: its worker process died before starting a "
                    f"unit (out of memory?); finished groups are kept, run the same command again "
                    f"to resume"
                ) from None
            crashes[uid] += 1
            print(
                f"refspatial-gen: unit {uid} killed its worker process ({crashes[uid]} of {MAX_UNIT_CRASHES})",
                file=sys.stderr,
            )
            if crashes[uid] >= MAX_UNIT_CRASHES:
                task = replace(task, skip=tuple(task.skip) + ((uid, "worker_crashed"),))
        finally:
            stop_pool(pool)
