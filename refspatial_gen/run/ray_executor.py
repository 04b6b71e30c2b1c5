"""Scale-out on Ray: the same shard-group tasks as the local pool, so the same bytes.

Without an address a local Ray instance with `workers` CPUs is started. On a cluster, pass
`--ray-address auto` (or ray://host:10001) and an `--out` folder on storage every node mounts (NFS, a
shared volume, a FUSE-mounted bucket): each task writes its own shard files and group record there.

Failures: Ray retries a task whose worker died (`RAY_RETRIES` times). When the retries run out, the unit
the worker was on (named in `_parts/shard-XXXXX.unit`) is blamed: the group is submitted again without it
and the unit is counted as dropped (`worker_crashed`), as in the local pool. A Python error inside a task
is re-raised as itself (e.g. the file a full disk could not take), never as a wrapped Ray traceback.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RunError

RAY_RETRIES = 2


def _unwrap(e: BaseException) -> BaseException:
    cause = getattr(e, "cause", None)
    return cause if isinstance(cause, BaseException) else e


def execute_on_ray(tasks: list, workers: int, address: str | None, out_dir: Path) -> Iterator[dict[str, Any]]:
    import ray
    from ray.exceptions import RayTaskError, WorkerCrashedError

    from refspatial_gen.run.executor import run_group
    from refspatial_gen.run.localpool import read_marker

    env = {
        k: os.environ[k]
        for k in (
            "MUJOCO_GL",
            "PYOPENGL_PLATFORM",
            "REFSPATIAL_SHARED_DATA",
            "REFSPATIAL_ALLOWED_ROOTS",
            "REFSPATIAL_FAULT",
        )
        if k in os.environ
    }
    started_here = not ray.is_initialized()
    if started_here:
        if address:
            ray.init(address=address, runtime_env={"env_vars": env}, log_to_driver=True)
        else:
            ray.init(
                num_cpus=max(1, workers), include_dashboard=False, runtime_env={"env_vars": env}, log_to_driver=True
            )
    pending: dict = {}
    try:
        remote = ray.remote(num_cpus=1, max_retries=RAY_RETRIES)(run_group)
        pending = {remote.remote(t): t for t in tasks}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                task = pending.pop(ref)
                try:
                    yield ray.get(ref)
                except WorkerCrashedError:
                    again = _without_crasher(task, read_marker(out_dir, task.group_index))
                    pending[remote.remote(again)] = again
                except RayTaskError as e:
                    raise _unwrap(e) from None
    finally:
        for ref in pending:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # noqa: BLE001 - best effort while stopping; the shutdown below ends them anyway
                pass
        if started_here:
            ray.shutdown()


def _without_crasher(task: Any, uid: str | None) -> Any:
    """The group again, minus the unit that killed its worker RAY_RETRIES + 1 times in a row."""
    if uid is None or uid in dict(task.skip):
        raise RunError(
            f"shard group {task.group_index}: its Ray worker died {RAY_RETRIES + 1} times"
            f"{'' if uid is None else f' on unit {uid}'} (out of memory? a node lost?); finished "
            f"groups are kept, run the same command again to resume"
        ) from None
    print(
        f"refspatial-gen: unit {uid} killed its Ray worker {RAY_RETRIES + 1} times; dropped (worker_crashed)",
        file=sys.stderr,
    )
    return replace(task, skip=tuple(task.skip) + ((uid, "worker_crashed"),))
