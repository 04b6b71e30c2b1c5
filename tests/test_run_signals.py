"""Ctrl-C, SIGTERM and a killed parent: the run stops its workers, leaves no process behind, says how to
resume (exit 130 / 143), and the resumed run is byte-identical to an uninterrupted one. A worker killed
mid-unit is survived: its unit is retried alone, then dropped as `worker_crashed`."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers.runs import output_digest, write_toy_recipe

pytestmark = pytest.mark.slow


def _args(recipe, out, workers=2, executor="local"):
    return [sys.executable, "-m", "refspatial_gen.cli", "shards", "--recipe", str(recipe), "--out", str(out),
            "--workers", str(workers), "--executor", executor, "--quiet", "--no-report"]


def _env(fault=None):
    env = {k: v for k, v in os.environ.items() if k != "REFSPATIAL_FAULT"}
    if fault:
        env["REFSPATIAL_FAULT"] = fault
    return env


def descendants(pid: int) -> set[int]:
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                kids = [int(x) for x in (task / "children").read_text().split()]
            except OSError:
                continue
            for k in kids:
                if k not in out:
                    out.add(k)
                    todo.append(k)
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def _wait_until_working(out, proc, n_workers, timeout=120):
    """Until the workers run units (their unit markers exist) and the pool's processes are up."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        kids = descendants(proc.pid)
        if len(list((out / "_parts").glob("*.unit"))) >= 1 and len(kids) >= n_workers:
            return kids
        time.sleep(0.1)
    raise AssertionError("the run never started its workers")


def _gone(pids, timeout=15):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if not [p for p in pids if alive(p)]:
            return True
        time.sleep(0.1)
    return False


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    d = tmp_path_factory.mktemp("clean")
    recipe = write_toy_recipe(d, scenes=8, per_shard=2)
    r = subprocess.run(_args(recipe, d / "out", workers=1), capture_output=True, text=True, env=_env())
    assert r.returncode == 0, r.stderr
    return recipe, output_digest(d / "out"), json.loads((d / "out" / "index.json").read_text())["stats"]


@pytest.mark.parametrize("sig, code, word, group", [(signal.SIGINT, 130, "interrupted", True),
                                                     (signal.SIGTERM, 143, "terminated", False)])
def test_signal_stops_workers_and_resume_is_identical(clean, tmp_path, sig, code, word, group):
    recipe, want, _ = clean
    out = tmp_path / "out"
    proc = subprocess.Popen(_args(recipe, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env("slow:1.5"), start_new_session=True)
    kids = _wait_until_working(out, proc, 2)
    if group:
        os.killpg(proc.pid, sig)  # Ctrl-C in a terminal reaches the whole foreground process group
    else:
        os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"refspatial-gen: {word}: ") and "run the same command again to resume" in last, err
    assert _gone(kids), [p for p in kids if alive(p)]
    assert not list(out.glob("*.partial")) and not (out / "index.json").exists()
    r = subprocess.run(_args(recipe, out), capture_output=True, text=True, env=_env())
    assert r.returncode == 0, r.stderr
    assert output_digest(out) == want


def test_workers_die_with_their_parent_and_resume_is_identical(clean, tmp_path):
    recipe, want, _ = clean
    out = tmp_path / "out"
    proc = subprocess.Popen(_args(recipe, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env("slow:1.5"), start_new_session=True)
    kids = _wait_until_working(out, proc, 2)
    proc.kill()
    proc.wait()
    assert _gone(kids), [p for p in kids if alive(p)]  # no worker keeps writing after its parent died
    r = subprocess.run(_args(recipe, out), capture_output=True, text=True, env=_env())
    assert r.returncode == 0, r.stderr
    assert output_digest(out) == want


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_a_unit_that_kills_its_worker_is_retried_then_dropped(clean, tmp_path, executor):
    if executor == "ray":
        pytest.importorskip("ray")
    recipe, _, stats = clean
    out = tmp_path / "out"
    victim = "s0/toy:000003"
    r = subprocess.run(_args(recipe, out, executor=executor), capture_output=True, text=True,
                       env=_env(f"crash:{victim}"), timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "Traceback" not in r.stderr and "BrokenProcessPool" not in r.stderr and "WorkerCrashedError" not in r.stderr
    assert f"unit {victim} killed its" in r.stderr
    got = json.loads((out / "index.json").read_text())["stats"]
    assert got["dropped"].get("worker_crashed") == 1
    assert got["units"] == stats["units"] and got["samples"] == stats["samples"] - 1
