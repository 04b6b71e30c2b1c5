"""`verify DIR` checks every shard's size and sha256 against index.json before re-checking QA pairs."""

import json
import subprocess
import sys

from refspatial_gen.recipe import load_recipe
from refspatial_gen.run.executor import RecipeRef, run_plan
from tests.helpers.runs import write_toy_recipe


def _verify(d):
    r = subprocess.run([sys.executable, "-m", "refspatial_gen.cli", "verify", str(d), "--json"], capture_output=True, text=True)
    return r.returncode, json.loads(r.stdout)


def test_verify_reports_altered_and_missing_shards(tmp_path):
    p = write_toy_recipe(tmp_path, scenes=4, per_shard=2)
    out = tmp_path / "o"
    run_plan(load_recipe(p), RecipeRef(str(p), None, None, None), out, workers=1, strict=True, progress=False)
    rc, res = _verify(out)
    assert rc == 0 and res["failed"] == 0 and res["qa_pairs"] > 0 and res["shard_problems"] == []
    shards = sorted(out.glob("shard-*.mcap"))
    data = bytearray(shards[0].read_bytes())
    data[len(data) // 2] ^= 0xFF
    shards[0].write_bytes(bytes(data))
    shards[1].unlink()
    rc, res = _verify(out)
    assert rc == 1
    problems = {(p["file"].rsplit("/", 1)[-1], p["problem"]) for p in res["shard_problems"]}
    assert problems == {(shards[0].name, "hash_mismatch"), (shards[1].name, "missing")}
