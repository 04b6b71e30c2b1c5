"""Crash-test hook of the executor: tests kill a run at a named point (after the N-th unit, while writing
the index, when starting a unit) through the REFSPATIAL_FAULT environment variable."""

from __future__ import annotations

import os
import signal
import time

FAULT_ENV = "REFSPATIAL_FAULT"  # test hook: "unit:N" | "index" — SIGKILL this process at that point

_units_done = 0


def fault(point: str, uid: str = "") -> None:
    """Crash-test hook: kill the process with SIGKILL at a named point when REFSPATIAL_FAULT asks for it
    ("unit:N" after the N-th unit, "index" while writing the index, "crash:<uid>" when starting that unit;
    "slow:SECONDS" only sleeps that long after every unit)."""
    global _units_done
    spec = os.environ.get(FAULT_ENV)
    if not spec:
        return
    if point == "start":
        if spec == f"crash:{uid}":
            os.kill(os.getpid(), signal.SIGKILL)
        return
    if point == "unit":
        if spec.startswith("slow:"):  # a slow run, for tests of what happens while a run is in progress
            time.sleep(float(spec[5:]))
            return
        _units_done += 1
        if spec == f"unit:{_units_done}":
            os.kill(os.getpid(), signal.SIGKILL)
    elif spec == point:
        os.kill(os.getpid(), signal.SIGKILL)
