"""The rewrite stage against a scripted server: timeouts, retries, bad JSON, dropped connections, slow
replies, format fallback; nothing lost, every outcome counted by reason, verify passes, reruns send no
request twice and give the same bytes, and `rewrite:` off is byte-identical to no section."""

import json
import threading
import time
from collections import Counter
from pathlib import Path

import pytest

from refspatial_gen.recipe import load_recipe
from refspatial_gen.rewrite.config import load_rewrite_config
from refspatial_gen.rewrite.facts import Facts
from refspatial_gen.rewrite.stage import Rewriter
from refspatial_gen.run.executor import RecipeRef, run_plan
from refspatial_gen.shards.reader import iter_raw, read_sample_meta
from refspatial_gen.tools.verify_dir import verify_dir
from tests.helpers.runs import output_digest, write_toy_recipe
from tests.helpers.scripted_llm import PROMPTS, ScriptedServer

TIMEOUT = 0.4


def _section(tmp: Path, url: str, **extra) -> str:
    (tmp / "prompts.yaml").write_text(PROMPTS)
    opts = {"server": url, "model": "scripted-1", "prompts": "prompts.yaml", "timeout": TIMEOUT, "retries": 2,
            "backoff": 0.01, "concurrency": 3, "cache": "cache", **extra}
    return "rewrite:\n" + "".join(f"  {k}: {json.dumps(v)}\n" for k, v in opts.items())


def _recipe(tmp: Path, section: str = "", scenes: int = 4) -> Path:
    p = write_toy_recipe(tmp, scenes=scenes, per_shard=2)
    p.write_text(p.read_text() + section)
    return p


def _run(p: Path, out: Path, workers: int = 1) -> dict:
    return run_plan(load_recipe(p), RecipeRef(str(p), None, None, None), out, workers=workers, strict=True,
                    progress=False)


def _metas(out: Path) -> list[dict]:
    return [m for s in sorted(out.glob("shard-*.mcap")) for m in read_sample_meta(s)]


@pytest.mark.slow
def test_scripted_server_every_pair_kept_or_counted_and_verify_passes(tmp_path):
    with ScriptedServer(slow_s=TIMEOUT * 3) as srv:
        (tmp_path / "a").mkdir()
        base = _run(_recipe(tmp_path / "a"), tmp_path / "plain")
        p = _recipe(tmp_path, _section(tmp_path, srv.url))
        res = _run(p, tmp_path / "out")
        st = srv.state
        # nothing lost: the same samples and pairs as without rewriting
        assert res["stats"]["qa_pairs"] == base["stats"]["qa_pairs"] and res["stats"]["samples"] == base["stats"]["samples"]
        metas = _metas(tmp_path / "out")
        plain = {q["qa_id"]: q["question"] for m in _metas(tmp_path / "plain") for q in m["qa"]}
        accepted = sum(m["meta"]["rewrite"]["accepted"] for m in metas)
        truth = Counter()
        for m in metas:
            truth.update({k[len("rewrite_"):]: v for k, v in (m["meta"].get("truth") or {}).items()
                          if k.startswith("rewrite_")})
        expected = Counter(st.expected.values())
        assert set(expected) == {"accepted", "server_error", "bad_json", "extra_object", "leaked_answer",
                                 "relation_changed"}, expected  # every scripted behaviour was exercised
        assert accepted == expected["accepted"] and truth == expected - Counter({"accepted": expected["accepted"]})
        assert accepted + sum(truth.values()) == len(plain)  # every pair was sent and is accounted for
        # kept rewrites replace the question and record the original; the others are the original, byte for byte
        for m in metas:
            pairs = m["meta"]["rewrite"]["pairs"]
            for q in m["qa"]:
                if q["qa_id"] in pairs:
                    assert pairs[q["qa_id"]]["original"] == plain[q["qa_id"]]
                    assert q["question"].startswith("Looking at the photo: ") and q["question"] != plain[q["qa_id"]]
                else:
                    assert q["question"] == plain[q["qa_id"]]
        # the client fell back from json_schema (refused) to json_object for the whole process: only the requests
        # already in flight (at most `concurrency`) were sent with json_schema
        assert 1 <= st.formats["json_schema"] <= 3 and st.formats["json_object"] >= len(st.expected)
        v = verify_dir(tmp_path / "out")
        assert v["failed"] == 0 and v["rewritten"] == accepted and not v["shard_problems"], v["failures"][:3]
        # a rerun into a fresh folder with the same cache: only the pairs that failed on the server are asked again
        n = st.requests
        _run(p, tmp_path / "out2")
        assert st.requests - n == expected["server_error"] * 3  # (1 + 2 retries) each, nothing else
        assert output_digest(tmp_path / "out") == output_digest(tmp_path / "out2")


def test_rewrite_off_is_byte_identical_to_no_section(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _run(_recipe(tmp_path / "a", scenes=2), tmp_path / "a" / "out")
    _run(_recipe(tmp_path / "b", _section(tmp_path / "b", "http://127.0.0.1:9/v1", enabled=False), scenes=2),
         tmp_path / "b" / "out")
    a, b = output_digest(tmp_path / "a" / "out"), output_digest(tmp_path / "b" / "out")
    a.pop("index.json"), b.pop("index.json")  # the index names the recipe's hash, which differs
    assert a and a == b


def test_verify_catches_a_rewrite_that_breaks_the_rules(tmp_path):
    """A stored rewrite edited after the fact (here: a relation flipped, an object added) fails verify."""
    from refspatial_gen.rewrite.verify import verify_rewrites
    from refspatial_gen.shards.reader import read_samples

    with ScriptedServer(force="good") as srv:
        _run(_recipe(tmp_path, _section(tmp_path, srv.url), scenes=3), tmp_path / "out")
    samples = [s for f in sorted((tmp_path / "out").glob("shard-*.mcap")) for s in read_samples(f)]
    assert all(not verify_rewrites(s) for s in samples)
    swaps = {" left": " right", " right": " left", "closer": "farther", "farther": "closer", "taller": "shorter",
             "shorter": "taller", " front": " back", "behind": "in front of", "bigger": "smaller", "smaller": "bigger"}
    s, q, w = next((s, q, w) for s in samples for q in s.qa if q.qa_id in s.meta["rewrite"]["pairs"]
                   for w in swaps if w in q.question)
    good = q.question
    q.question = good.replace(w, swaps[w], 1)
    bad = verify_rewrites(s)
    assert [f["qa_id"] for f in bad] == [q.qa_id] and "relation_changed" in bad[0]["reason"], (good, q.question, bad)
    q.question = good.replace("Looking at the photo: ", "Beside the robot: ")
    assert "extra_object" in verify_rewrites(s)[0]["reason"]
    q.question = good
    assert not verify_rewrites(s)
    s.meta["rewrite"]["pairs"][q.qa_id]["suffix"] = "(A) maybe"
    assert "suffix" in verify_rewrites(s)[0]["reason"]


def test_rewrite_command_copies_everything_but_the_questions_and_resumes(tmp_path):
    from refspatial_gen.cli import main

    (tmp_path / "src").mkdir()
    _run(_recipe(tmp_path / "src", scenes=3), tmp_path / "plain")
    with ScriptedServer(force="good") as srv:
        cfg = tmp_path / "rw.yaml"
        cfg.write_text(_section(tmp_path, srv.url, cache=str(tmp_path / "c")))
        assert main(["rewrite", str(tmp_path / "plain"), "--out", str(tmp_path / "rw"), "--config", str(cfg),
                     "--quiet"]) == 0
        sent = srv.state.requests
        assert main(["rewrite", str(tmp_path / "plain"), "--out", str(tmp_path / "rw2"), "--config", str(cfg),
                     "--quiet"]) == 0
        assert srv.state.requests == sent  # all from the cache
        first = output_digest(tmp_path / "rw")
        (tmp_path / "rw" / sorted(p.name for p in (tmp_path / "rw").glob("shard-*.mcap"))[-1]).write_bytes(b"torn")
        assert main(["rewrite", str(tmp_path / "plain"), "--out", str(tmp_path / "rw"), "--config", str(cfg),
                     "--quiet"]) == 0  # resume: intact shards kept, the damaged one redone from the cache
        assert srv.state.requests == sent and output_digest(tmp_path / "rw") == first
    assert output_digest(tmp_path / "rw") == output_digest(tmp_path / "rw2")
    for f in sorted((tmp_path / "plain").glob("shard-*.mcap")):
        for a, b in zip(iter_raw(f), iter_raw(tmp_path / "rw" / f.name)):
            assert [t for t in a.messages if a.messages[t] != b.messages[t]] == ["/sample", "/qa"]
    v = verify_dir(tmp_path / "rw")
    assert v["failed"] == 0 and v["rewritten"] == v["qa_pairs"] > 0
    idx = json.loads((tmp_path / "rw" / "index.json").read_text())
    assert idx["rewrite"]["model"] == "scripted-1" and idx["totals"]["qa_pairs"] == v["qa_pairs"]


def test_requests_in_flight_are_bounded_by_concurrency():
    cfg = load_rewrite_config({"model": "m", "concurrency": 3}, "recipes/x.yaml", {})
    lock, live, peak = threading.Lock(), [0], [0]

    class Slow:
        requests = 0

        def complete(self, body, mode, schema=None):
            with lock:
                live[0] += 1
                peak[0] = max(peak[0], live[0])
            time.sleep(0.05)
            with lock:
                live[0] -= 1
            return "{}"

    class NoCache(Rewriter):
        def reply(self, body):
            return self.client.complete(body, "none")

    rw = NoCache(cfg, "/nonexistent", client=Slow())

    f = Facts("q", "locate", "points", "point", "Point to the cup.", "", "[(0.5, 0.5)]", ("the cup",), (), (), frozenset())
    futs = [rw._pool.submit(rw._reply_or_error, rw.request(f)) for _ in range(12)]
    assert all(x.result() == "{}" for x in futs)
    rw.close()
    assert peak[0] == 3


@pytest.mark.parametrize("bad,where", [("concurrency: 0", "concurrency"), ("temprature: 1", "temprature"),
                                       ("prompts: missing.yaml", "prompt file")])
def test_bad_rewrite_section_is_a_recipe_error(tmp_path, bad, where):
    from refspatial_gen.core.errors import RecipeError, RecipeErrors

    p = _recipe(tmp_path, f"rewrite:\n  model: m\n  {bad}\n")
    with pytest.raises((RecipeError, RecipeErrors)) as e:
        load_recipe(p)
    assert where in str(e.value) and "toy.yaml:" in str(e.value)
