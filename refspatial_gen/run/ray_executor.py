"""Scale-out on Ray: the same shard-group tasks as the local pool, so the same bytes.

Without an address a local Ray instance with `workers` CPUs is started. On a cluster, pass
`--ray-address auto` (or ray://host:10001) and an `--out` folder on storage every node mounts (NFS, a
shared volume, a FUSE-mounted bucket): each task writes its own shard files and group record there.
"""

from __future__ import annotations

import os
from typing import Any, Iterator


def execute_on_ray(tasks: list, workers: int, address: str | None) -> Iterator[dict[str, Any]]:
    import ray

    from refspatial_gen.run.executor import run_group

    env = {k: os.environ[k] for k in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "REFSPATIAL_SHARED_DATA") if k in os.environ}
    started_here = not ray.is_initialized()
    if started_here:
        if address:
            ray.init(address=address, runtime_env={"env_vars": env}, log_to_driver=True)
        else:
            ray.init(num_cpus=max(1, workers), include_dashboard=False, runtime_env={"env_vars": env},
                     log_to_driver=True)
    try:
        remote = ray.remote(num_cpus=1, max_retries=2)(run_group)
        pending = [remote.remote(t) for t in tasks]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield ray.get(ref)
    finally:
        if started_here:
            ray.shutdown()
