"""One run per output folder: an exclusive lock held for the run's whole life.

Why: two runs writing one folder corrupt each other's shards, and `--fresh` would delete the files of a run
in progress. The lock is `flock` on `<out>/.lock` (the kernel releases it when the process dies, SIGKILL
included, so a crashed run never leaves a lock behind), and the file names its holder (pid, host, start
time, command) so a refused run can say who holds it. Where the filesystem has no working `flock`
(some network mounts), the holder record itself is the lock: a record naming a process that no longer
exists on this host is stale and taken over; one naming another host is respected until removed by hand.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RunError

LOCK_NAME = ".lock"


def _host() -> str:
    return socket.gethostname()


def pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by someone else
    return True


def describe(holder: dict[str, Any]) -> str:
    return (
        f"pid {holder.get('pid', '?')} on {holder.get('host', '?')} since {holder.get('started', '?')} "
        f"({holder.get('command', '?')})"
    )


def _read_holder(fd: int) -> dict[str, Any]:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        raw = os.read(fd, 65536)
        d = json.loads(raw.decode("utf-8")) if raw.strip() else {}
        return d if isinstance(d, dict) else {}
    except (OSError, ValueError):
        return {}


class OutputLock:
    """`with OutputLock(out_dir):` holds the folder for the block; raises RunError (exit 3) when held."""

    def __init__(self, out_dir: Path) -> None:
        self.path = Path(out_dir) / LOCK_NAME
        self.fd: int | None = None

    def acquire(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            holder = _read_holder(fd)
            os.close(fd)
            if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise RunError(
                    f"{self.path.parent} is in use by another run: {describe(holder)}; wait for it "
                    f"to finish or use another --out",
                    3,
                ) from None
            if e.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
                raise
            fd = self._acquire_without_flock()
        self.fd = fd
        me = {
            "pid": os.getpid(),
            "host": _host(),
            "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
            "command": " ".join(sys.argv[:1] + sys.argv[1:])[:300],
        }
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(me, sort_keys=True).encode("utf-8"), 0)
        os.fsync(fd)

    def _acquire_without_flock(self) -> int:
        """No flock here: honour a live holder's record; take over a stale one (dead pid on this host)."""
        fd = os.open(self.path, os.O_RDWR)
        holder = _read_holder(fd)
        if holder and holder.get("pid") != os.getpid():
            same_host = holder.get("host") == _host()
            if not same_host or pid_alive(int(holder.get("pid", 0))):
                os.close(fd)
                hint = "" if same_host else f"; if that run is dead, remove {self.path}"
                raise RunError(f"{self.path.parent} is in use by another run: {describe(holder)}{hint}", 3)
        return fd

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            os.ftruncate(self.fd, 0)  # an empty record: nobody holds it (the file itself stays)
        except OSError:
            pass
        try:
            fcntl.flock(self.fd, fcntl.LOCK_UN)
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None

    def __enter__(self) -> OutputLock:
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()
