"""Crash safety: a run killed with SIGKILL at several points and restarted ends byte-identical to a clean run."""

import os
import signal
import subprocess
import sys

import pytest

from tests.helpers.runs import output_digest, write_toy_recipe

pytestmark = pytest.mark.slow


def _run(recipe, out, fault=None):
    env = dict(os.environ)
    env.pop("REFSPATIAL_FAULT", None)
    if fault:
        env["REFSPATIAL_FAULT"] = fault
    return subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "shards", "--recipe", str(recipe), "--out",
                           str(out), "--workers", "1", "--quiet", "--strict", "--no-report"],
                          capture_output=True, text=True, env=env)


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    d = tmp_path_factory.mktemp("clean")
    recipe = write_toy_recipe(d, scenes=9, per_shard=4)
    assert _run(recipe, d / "out").returncode == 0
    return recipe, output_digest(d / "out")


@pytest.mark.parametrize("fault", ["unit:1", "unit:6", "unit:8", "index"])
def test_sigkill_then_restart_is_byte_identical(clean, tmp_path, fault):
    recipe, want = clean
    out = tmp_path / "out"
    r = _run(recipe, out, fault)
    assert r.returncode == -signal.SIGKILL, (r.returncode, r.stderr)
    assert not (out / "index.json").exists()
    r = _run(recipe, out)
    assert r.returncode == 0, r.stderr
    assert output_digest(out) == want
    assert not list(out.glob("*.partial")) and not list(out.glob("*.tmp"))


def test_corrupted_finished_shard_is_redone(clean, tmp_path):
    recipe, want = clean
    out = tmp_path / "out"
    assert _run(recipe, out).returncode == 0
    victim = sorted(out.glob("shard-*.mcap"))[1]
    victim.write_bytes(victim.read_bytes()[:-100])
    assert _run(recipe, out).returncode == 0
    assert output_digest(out) == want


def test_ray_executor_gives_identical_bytes(clean, tmp_path):
    pytest.importorskip("ray")
    recipe, want = clean
    out = tmp_path / "ray"
    r = subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "shards", "--recipe", str(recipe), "--out", str(out),
                        "--workers", "2", "--executor", "ray", "--quiet", "--strict", "--no-report"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    assert output_digest(out) == want
