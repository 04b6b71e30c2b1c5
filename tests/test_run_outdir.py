"""One run per output folder (lock), the input's content in the run's identity, no stray shard files,
and a failed write that names its file."""

import errno
import fcntl
import json
import os
import resource
import signal
import socket
import subprocess
import sys
import time

import pytest

from refspatial_gen.core.errors import OutputIOError, RunError
from refspatial_gen.recipe import load_recipe
from refspatial_gen.run import lock as L
from refspatial_gen.run.executor import RecipeRef, run_plan
from refspatial_gen.run.manifest import input_manifest
from refspatial_gen.sources import register_source
from refspatial_gen.sources.toy import ToySource
from tests.helpers.runs import output_digest, write_toy_recipe


def _cli(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "refspatial_gen.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _wait_for_holder(out, proc, timeout=60):
    t0 = time.time()
    while time.time() - t0 < timeout:
        p = out / ".lock"
        if p.is_file() and p.read_text().strip() and (out / "_parts" / "run.json").is_file():
            return json.loads(p.read_text())
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("the first run never took the lock")


@pytest.mark.slow
def test_second_concurrent_run_is_refused_at_once_with_the_holder_named(tmp_path):
    recipe = write_toy_recipe(tmp_path, scenes=8, per_shard=2)
    out = tmp_path / "out"
    args = ["shards", "--recipe", str(recipe), "--out", str(out), "--workers", "1", "--quiet", "--no-report"]
    first = _cli(*args, env={**os.environ, "REFSPATIAL_FAULT": "slow:2"})
    try:
        holder = _wait_for_holder(out, first)
        assert holder["pid"] == first.pid and holder["host"] == socket.gethostname()
        for extra in ([], ["--fresh"]):
            t0 = time.time()
            second = subprocess.run([sys.executable, "-m", "refspatial_gen.cli", *args, *extra], capture_output=True,
                                    text=True, timeout=120)
            assert second.returncode == 3, second.stderr
            assert f"is in use by another run: pid {first.pid} on {socket.gethostname()}" in second.stderr
            assert "Traceback" not in second.stderr and len(second.stderr.strip().splitlines()) == 1
            assert time.time() - t0 < 30  # refused at once (start-up time only), not after planning or waiting
        assert first.wait(timeout=600) == 0, first.stderr.read()
    finally:
        if first.poll() is None:
            first.kill()
    # --fresh did not delete the first run's files: a clean run gives the same bytes
    clean = tmp_path / "clean"
    assert subprocess.run([sys.executable, "-m", "refspatial_gen.cli", *args[:4], str(clean), *args[5:]]).returncode == 0
    assert output_digest(out) == output_digest(clean)
    assert (out / ".lock").read_text() == ""  # released


def test_lock_is_exclusive_in_one_process_and_released(tmp_path):
    a = L.OutputLock(tmp_path)
    a.acquire()
    with pytest.raises(RunError, match=f"pid {os.getpid()}") as ei:
        L.OutputLock(tmp_path).acquire()
    assert ei.value.code == 3
    a.release()
    with L.OutputLock(tmp_path):
        pass


@pytest.mark.parametrize("holder, refused", [
    ({"pid": 1, "host": socket.gethostname()}, True),  # alive on this host
    ({"pid": 2**22 + 12345, "host": socket.gethostname()}, False),  # dead on this host: stale, taken over
    ({"pid": 4242, "host": "another-node"}, True)])  # another host: cannot be checked, respected
def test_stale_lock_detection_by_pid_and_host_without_flock(tmp_path, monkeypatch, holder, refused):
    (tmp_path / ".lock").write_text(json.dumps({**holder, "started": "then", "command": "x"}))

    def no_flock(fd, op):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(fcntl, "flock", no_flock)
    lk = L.OutputLock(tmp_path)
    if refused:
        with pytest.raises(RunError, match=f"pid {holder['pid']} on {holder['host']}"):
            lk.acquire()
    else:
        lk.acquire()
        assert json.loads((tmp_path / ".lock").read_text())["pid"] == os.getpid()
        lk.release()


def test_a_record_left_by_a_killed_run_does_not_block(tmp_path):
    (tmp_path / ".lock").write_text(json.dumps({"pid": 2**22 + 1, "host": socket.gethostname()}))
    with L.OutputLock(tmp_path):  # flock is free: the kernel released it when that process died
        pass


class DirSource(ToySource):
    """The toy world, but with an input folder (so the run's identity includes the input's content)."""

    name = "toydir"


def _dir_run(tmp_path, data, out, **kw):
    register_source("toydir", "tests.test_run_outdir:DirSource")
    p = write_toy_recipe(tmp_path, scenes=4, per_shard=2)
    p.write_text(p.read_text().replace("  - kind: toy\n", "  - kind: toydir\n    input: data\n"))
    return run_plan(load_recipe(p), RecipeRef(str(p), None, None, None), out, workers=1, strict=True,
                    progress=False, **kw)


def test_a_different_input_with_the_same_folder_name_is_refused(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "a.txt").write_text("first dataset")
    _dir_run(tmp_path, data, tmp_path / "out")
    _dir_run(tmp_path, data, tmp_path / "out")  # same input: resumes (nothing to redo)
    (data / "a.txt").write_text("other dataset")  # same folder name, same file names, other content
    with pytest.raises(RunError, match=r"input of sources\[0\] \(content differs\)") as ei:
        _dir_run(tmp_path, data, tmp_path / "out")
    assert ei.value.code == 2
    _dir_run(tmp_path, data, tmp_path / "out", fresh=True)


def test_manifest_hashes_contents_once(tmp_path):
    data = tmp_path / "d"
    (data / "sub").mkdir(parents=True)
    for i in range(5):
        (data / "sub" / f"{i}.bin").write_bytes(os.urandom(1000 + i))
    cache = tmp_path / "cache.json"
    first = input_manifest(data, cache)
    assert first["files"] == 5 and first["hashed_now"] == 5
    again = input_manifest(data, cache)
    assert again["hashed_now"] == 0 and again["digest"] == first["digest"]
    (data / "sub" / "3.bin").write_bytes(b"changed")
    changed = input_manifest(data, cache)
    assert changed["hashed_now"] == 1 and changed["digest"] != first["digest"]
    copy = tmp_path / "copy" / "d"
    copy.parent.mkdir()
    os.rename(data, copy)
    assert input_manifest(copy)["digest"] == changed["digest"]  # content, not place or mtime


def test_resume_leaves_no_stray_shard_files(tmp_path):
    recipe = write_toy_recipe(tmp_path, scenes=5, per_shard=2)
    out = tmp_path / "out"
    ref = RecipeRef(str(recipe), None, None, None)
    run_plan(load_recipe(recipe), ref, out, workers=1, strict=True, progress=False)
    want = output_digest(out)
    for name in ("shard-00099.mcap", "shard-00001.mcap.partial", "shard-00002-extra.mcap"):
        (out / name).write_bytes(b"stray")
    (out / "_parts" / "shard-00042.json").write_text("{}")
    res = run_plan(load_recipe(recipe), ref, out, workers=1, strict=True, progress=False)
    listed = {s["name"] for s in res["index"]["shards"]}
    assert {p.name for p in out.glob("shard-*")} == listed
    assert not (out / "_parts" / "shard-00042.json").exists()
    assert output_digest(out) == want


def test_a_failed_write_names_the_file(tmp_path, monkeypatch):
    from refspatial_gen.shards import writer as W

    def full(self, sample):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(W.ShardWriter, "write", full)
    recipe = write_toy_recipe(tmp_path, scenes=3, per_shard=2)
    with pytest.raises(OutputIOError, match=r"cannot write .*shard-00000\.mcap: No space left on device"):
        run_plan(load_recipe(recipe), RecipeRef(str(recipe), None, None, None), tmp_path / "out", workers=1,
                 progress=False)
    assert not list((tmp_path / "out").glob("shard-*"))  # the unfinished group's files are discarded


@pytest.mark.slow
def test_a_real_write_error_is_one_line_naming_the_file(tmp_path):
    """RLIMIT_FSIZE makes writes past 64 kB fail with EFBIG, the way a full disk fails them."""
    recipe = write_toy_recipe(tmp_path, scenes=6, per_shard=6)

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))

    r = subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "shards", "--recipe", str(recipe), "--out",
                        str(tmp_path / "out"), "--workers", "2", "--quiet", "--no-report"],
                       capture_output=True, text=True, preexec_fn=limit, timeout=600)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert lines[-1].startswith("refspatial-gen: cannot write ") and "shard-00000.mcap" in lines[-1]
    assert "File too large" in lines[-1]
