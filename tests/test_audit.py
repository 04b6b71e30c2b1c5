"""Audit: stratified reproducible sample over several datasets, review page, verdicts through the server and
the CLI, and rates with Wilson intervals."""

from __future__ import annotations

import json
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from refspatial_gen.audit.sample import Item, parse_dataset_args, stratified
from refspatial_gen.audit.verdicts import Verdict, append_verdict, read_verdicts, summarise, wilson
from refspatial_gen.cli import main as cli_main
from refspatial_gen.recipe import load_recipe
from refspatial_gen.run.executor import RecipeRef, run_plan
from tests.helpers.runs import write_toy_recipe


@pytest.fixture(scope="module")
def two_datasets(tmp_path_factory) -> tuple[Path, Path]:
    out = []
    for name, scenes in (("a", 6), ("b", 3)):
        d = tmp_path_factory.mktemp(name)
        rp = write_toy_recipe(d, scenes=scenes, per_shard=2)
        recipe = load_recipe(rp)
        run_plan(recipe, RecipeRef(str(rp), None, None, None), d / "out", workers=1, progress=False)
        out.append(d / "out")
    return out[0], out[1]


def _item(label: str, fam: str, steps: int, k: int) -> Item:
    return Item(label, 0, "shard-00000.mcap", 0, "s", k, f"q{fam}{steps}:{k:02d}", fam, steps, "toy")


def test_stratified_sample_gives_every_dataset_its_floor_and_rare_strata_before_common_ones():
    big = [_item("big", "locate", 1, k) for k in range(200)] + [_item("big", "choice", 5, k) for k in range(2)]
    small = [_item("small", "locate", 2, k) for k in range(10)]
    picked = stratified({"big": big, "small": small}, n=30, seed=3, min_per_label=8)
    assert len(picked) == 30
    labels = [it.label for it in picked]
    assert labels.count("small") == 10  # all it has: 8 floor + 2 when the rest is shared out by fewest picks
    assert sum(1 for it in picked if it.family == "choice") == 2  # the rare 5-step stratum is not starved
    assert stratified({"big": big, "small": small}, 30, 3, 8) == picked  # reproducible
    assert stratified({"big": big, "small": small}, 30, 4, 8) != picked
    assert len({it.item_id for it in picked}) == 30


def test_dataset_arguments_may_share_a_label_but_not_a_folder():
    from refspatial_gen.audit.sample import parts

    pairs = parse_dataset_args(["x=/a", "/b/y", "x=/c"])
    assert pairs == [("x", Path("/a")), ("y", Path("/b/y")), ("x", Path("/c"))]
    assert parts(pairs) == [("x", 0, Path("/a")), ("y", 0, Path("/b/y")), ("x", 1, Path("/c"))]
    with pytest.raises(ValueError, match="twice"):
        parse_dataset_args(["x=/a", "z=/a"])


def test_wilson_interval_matches_known_values():
    lo, hi = wilson(2, 150)
    assert abs(lo - 0.00366) < 1e-4 and abs(hi - 0.0473) < 1e-3
    assert wilson(0, 0) == (0.0, 1.0)
    lo, hi = wilson(0, 30)
    assert lo == 0.0 and 0.11 < hi < 0.12


def test_audit_page_verdicts_and_summary_end_to_end(two_datasets, tmp_path, capsys):
    a, b = two_datasets
    out = tmp_path / "audit"
    assert cli_main(["audit", f"sim={a}", f"scan={b}", "--n", "12", "--min-per-dataset", "4", "--out", str(out)]) == 0
    items = [json.loads(x) for x in (out / "sample.jsonl").read_text().splitlines()]
    assert len(items) == 12 and {it["label"] for it in items} == {"sim", "scan"}
    assert sum(it["label"] == "scan" for it in items) >= 4
    for it in items:  # every item has its rendered overlay, its question, and the objects it names with crops
        assert (out / it["png"]).is_file() and it["question"] and it["answer"]
        for o in it["objects"]:
            assert o["category"] and o["visible_px"] is not None and (out / o["crop"]).is_file()
    page = (out / "index.html").read_text()
    assert page.count('class="item"') == 12 and "verdicts.jsonl" in page
    first = (out / "sample.jsonl").read_bytes()
    assert cli_main(["audit", f"sim={a}", f"scan={b}", "--n", "12", "--min-per-dataset", "4", "--out", str(out)]) == 0
    assert (out / "sample.jsonl").read_bytes() == first  # the same command gives the same sample

    ids = [it["item_id"] for it in items]
    assert cli_main(["audit", "mark", str(out), ids[0], "wrong", "--note", "answer on the wrong mug"]) == 0
    assert cli_main(["audit", "mark", str(out), ids[1], "ambiguous"]) == 0
    assert cli_main(["audit", "mark", str(out), "nope/x", "right"]) == 2  # unknown item: refused
    assert cli_main(["audit", "mark", str(out), ids[2], "fine"]) == 2  # unknown verdict word: refused

    from refspatial_gen.audit.serve import make_server

    server = make_server(out, 0)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}"
        assert urllib.request.urlopen(f"{url}/index.html").status == 200
        for item_id in ids[2:]:
            req = urllib.request.Request(f"{url}/verdict", json.dumps({"item_id": item_id, "verdict": "right"}).encode(),
                                         {"Content-Type": "application/json"})
            assert urllib.request.urlopen(req).status == 204
        bad = urllib.request.Request(f"{url}/verdict", b'{"item_id": "x", "verdict": "right"}')
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(bad)
        assert e.value.code == 400
    finally:
        server.shutdown()
        server.server_close()

    append_verdict(out, Verdict(ids[1], "right", "looked again: fine"))  # the last verdict wins
    v = read_verdicts(out)
    assert len(v) == 12 and v[ids[1]].verdict == "right"
    s = summarise(out)
    assert s["unjudged"] == 0 and s["overall"]["wrong"]["count"] == 1 and s["overall"]["right"]["count"] == 11
    assert s["problems"] == [{"item_id": ids[0], "family": items[0]["family"], "steps": items[0]["steps"],
                              "label": items[0]["label"], "verdict": "wrong", "note": "answer on the wrong mug"}]
    assert set(s["by_label"]) == {"sim", "scan"}
    capsys.readouterr()
    assert cli_main(["audit", "summary", str(out), "--markdown"]) == 0
    md = capsys.readouterr().out
    assert "answer on the wrong mug" in md and "| **all** | 12 | 11 |" in md


def test_audit_of_a_folder_that_is_not_a_dataset_is_a_clear_error(tmp_path, capsys):
    assert cli_main(["audit", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "refspatial-gen audit:" in capsys.readouterr().err
    assert cli_main(["audit", "summary", str(tmp_path)]) == 2
