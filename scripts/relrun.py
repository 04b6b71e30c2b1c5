"""Running one reliability case: the real command line, in this process, with a time limit.

A case sets up a temporary folder (a mutated copy of a shared sample, or a mutated recipe) and names the
command to run; the outcome is classified against what the case expects:

  error   exit 2 and one `file:line: message` / `path: message` line per problem, nothing written
  drop    exit 0 or 1, the named reason counted in index.json (and never `internal_error`)
  ok      exit 0 with samples (a variant that is valid, e.g. .ppm frames)

Anything else is a failure: a traceback (the CLI's last-resort handler fired), a hang (past the time
limit), silent acceptance (exit 0 without the expected drop), or a leak (output that quotes a file the
recipe must not read).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
import signal
import stat
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

REPO = Path(__file__).resolve().parents[1]
LEAK_MARKERS = ("root:x:0:0", "root:!:", "root:*:", "daemon:x:")


class Hang(BaseException):
    """Raised by the alarm: not an Exception, so nothing on the way up can swallow it."""


@dataclass
class Case:
    group: str
    name: str
    setup: Callable[[Path], tuple[list[str], Path | None]]  # tmp -> (argv, out folder to inspect)
    expect: str  # "error" | "lint-error" | "lint-ok" | "drop" | "ok"
    reasons: tuple[str, ...] = ()  # for "drop": any of these must be counted
    cwd: bool = False  # run with the temporary folder as working directory


@dataclass
class Outcome:
    case: Case
    ok: bool
    summary: str
    seconds: float
    detail: dict = field(default_factory=dict)


def writable_copy(src: Path, dst: Path) -> Path:
    """Copy a (read-only) shared sample and make the copy writable, so cases can damage it."""
    shutil.copytree(src, dst, symlinks=True)
    for dirpath, dirnames, filenames in os.walk(dst):
        os.chmod(dirpath, 0o755)
        for f in filenames:
            p = os.path.join(dirpath, f)
            if not os.path.islink(p):
                os.chmod(p, stat.S_IRUSR | stat.S_IWUSR | stat.S_IRGRP | stat.S_IROTH)
    return dst


def run_cli(argv: list[str], cwd: Path | None, limit_s: int) -> tuple[int | None, str, str, float, bool]:
    """refspatial_gen.cli.main(argv) with stdout/stderr captured; (rc, out, err, seconds, hung)."""
    from refspatial_gen.cli import main

    out, err = io.StringIO(), io.StringIO()
    old_cwd = os.getcwd()

    def alarm(signum, frame):
        raise Hang()

    prev = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(limit_s)
    t0 = time.perf_counter()
    rc: int | None = None
    hung = False
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main(argv)
            except SystemExit as e:  # argparse
                rc = e.code if isinstance(e.code, int) else 2
            except Exception as e:  # noqa: BLE001 - escaping main() = a traceback the user would see
                err.write(f"\nTraceback (escaped main): {type(e).__name__}: {e}\n")
    except Hang:
        hung = True
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, prev)
        os.chdir(old_cwd)
    return rc, out.getvalue(), err.getvalue(), time.perf_counter() - t0, hung


def _short(text: str, tmp: Path, limit: int = 110) -> str:
    t = text.replace(str(tmp) + os.sep, "").replace(str(tmp), ".").replace(str(REPO) + os.sep, "")
    t = " ".join(t.split())
    return t if len(t) <= limit else t[: limit - 3] + "..."


def _stats(out_dir: Path | None) -> dict:
    if out_dir is None or not (out_dir / "index.json").is_file():
        return {}
    try:
        return json.loads((out_dir / "index.json").read_bytes()).get("stats", {})
    except ValueError:
        return {}


_LINE = re.compile(r"^(\S[^:]*|--[a-z-]+):(\d+:)? \S")


def classify(case: Case, tmp: Path, limit_s: int = 120) -> Outcome:
    argv, out_dir = case.setup(tmp)
    rc, out, err, secs, hung = run_cli(argv, tmp if case.cwd else None, limit_s)
    text = out + err
    if hung:
        return Outcome(case, False, f"HANG (> {limit_s} s)", secs)
    if "Traceback" in text or "internal error" in text:
        return Outcome(case, False, "TRACEBACK: " + _short(err.strip().splitlines()[-1], tmp), secs)
    if any(m in text for m in LEAK_MARKERS):
        return Outcome(case, False, "LEAK: output quotes a protected file", secs)
    if (tmp / "PWNED").exists():
        return Outcome(case, False, "EXECUTED: a YAML tag ran a command", secs)
    if case.expect == "lint-ok":
        good = rc == 0 and out.startswith("ok:")
        return Outcome(case, good, "ok (lints clean)" if good else f"BASELINE INVALID (exit {rc}) {_short(out + err, tmp)}",
                       secs)
    if case.expect == "lint-error":
        lines = [ln for ln in out.strip().splitlines() if ln.strip()]
        good = rc == 1 and lines and all(_LINE.match(ln) for ln in lines) and not out.startswith("ok:")
        first = _short(lines[0], tmp) if lines else ""
        more = f" (+{len(lines) - 1} more)" if len(lines) > 1 else ""
        return Outcome(case, bool(good), f"error `{first}`{more}" if good else f"NOT REFUSED (exit {rc}) {first}", secs)
    st = _stats(out_dir)
    dropped = st.get("dropped", {})
    if any(k.startswith("internal_error") for k in dropped):
        return Outcome(case, False, f"INTERNAL DROP {dropped}", secs)
    if case.expect == "error":
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        if lines and lines[0].startswith("usage:") and ": error: " in lines[-1]:  # argparse's own refusal
            lines = lines[-1:]
        good = rc == 2 and lines and all(_LINE.match(ln) for ln in lines)
        first = _short(lines[0], tmp) if lines else ""
        return Outcome(case, bool(good), f"error `{first}`" if good else f"NOT REFUSED (exit {rc}) {first}", secs)
    if case.expect == "drop":
        hit = {r: n for r, n in dropped.items() if r in case.reasons}
        units = st.get("units", 0)
        if rc in (0, 1) and hit:
            r, n = sorted(hit.items())[0]
            return Outcome(case, True, f"drop `{r}` ({n} of {units} units)", secs, {"dropped": dropped})
        return Outcome(case, False, f"SILENT (exit {rc}, dropped {dropped or 'nothing'}) {_short(err, tmp, 80)}", secs)
    ok = rc == 0 and st.get("samples", 0) > 0
    return Outcome(case, ok, f"ok ({st.get('samples', 0)} samples)" if ok else f"FAILED (exit {rc}) {_short(err, tmp)}",
                   secs)
