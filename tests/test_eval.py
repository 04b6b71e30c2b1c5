"""`refspatial-gen eval`, the training exports and the splits on one small toy-source run."""

import json
from pathlib import Path

import numpy as np
import pytest

from refspatial_gen.cli import main
from refspatial_gen.rewards.parse import parse_points

TEMPLATES = Path(__file__).resolve().parents[1] / "recipes" / "templates"
RECIPE = f"""\
name: toy-eval
seed: 5
scenes: 10
sources:
  - kind: toy
    config: {{min_objects: 4, max_objects: 7}}
qa:
  families:
    locate: {{weight: 1.0, templates: [{TEMPLATES}/locate.yaml]}}
    identify: {{weight: 1.0, templates: [{TEMPLATES}/identify.yaml]}}
    placement: {{weight: 1.0, templates: [{TEMPLATES}/placement.yaml]}}
    choice: {{weight: 1.0, templates: [{TEMPLATES}/choice.yaml]}}
    quantitative: {{weight: 1.0, templates: [{TEMPLATES}/quantitative.yaml]}}
shards:
  samples_per_shard: 4
splits:
  fractions: {{train: 0.6, val: 0.2, test: 0.2}}
  unseen:
    categories: [tray]
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("evalrun")
    (d / "r.yaml").write_text(RECIPE)
    assert main(["shards", "--recipe", str(d / "r.yaml"), "--out", str(d / "out"), "--quiet", "--no-report"]) == 0
    assert main(["export", str(d / "out"), "--format", "jsonl", "--out", str(d / "jsonl")]) == 0
    qa = [json.loads(line) for line in (d / "jsonl" / "qa.jsonl").read_text().splitlines()]
    return d, qa


def _eval(capsys, out: Path, preds: list[dict], *extra) -> dict:
    p = out.parent / "p.jsonl"
    p.write_text("".join(json.dumps(x) + "\n" for x in preds))
    capsys.readouterr()
    assert main(["eval", str(out), "--predictions", str(p), "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def _gold(q):
    return q["trace"] or q["answer"]


def test_gold_scores_one_and_no_scene_in_two_splits(run, capsys):
    d, qa = run
    s = _eval(capsys, d / "out", [{"id": q["id"], "text": _gold(q)} for q in qa])
    assert s["n"] == len(qa) and s["success_rate"] == 1.0 and s["reward"] == 1.0 and s["parse_failures"] == 0
    assert {"n", "success_rate", "by_family", "by_steps", "parse_failures"} <= set(s)
    assert all(v["mean"] in (None, 1.0) for v in s["components"].values())
    assert set(s["by_family"]) >= {"locate", "identify", "placement", "choice", "quantitative"}
    idx = json.loads((d / "out" / "index.json").read_text())
    seen: dict[str, str] = {}
    for name, scenes in idx["splits"]["scenes"].items():
        for sc in scenes:
            assert sc not in seen, f"scene {sc} in {seen[sc]} and {name}"
            seen[sc] = name
    assert idx["splits"]["scenes"]["unseen"] and idx["splits"]["unseen_reasons"] == {"category:tray": len(idx["splits"]["scenes"]["unseen"])}
    assert set(s["by_split"]) == {n for n, sc in idx["splits"]["scenes"].items() if sc}


def _move(q, fn):
    W, H = q["image_size"]
    pts = parse_points(q["answer"], W, H)
    new = "[" + ", ".join(f"({a / W:.3f}, {b / H:.3f})" for a, b in (fn(x, y, W, H) for x, y in pts)) + "]"
    return q["trace"].replace(f"<answer>{q['answer']}</answer>", f"<answer>{new}</answer>") if q["trace"] else new


def test_moved_swapped_and_reordered(run, capsys):
    d, qa = run
    pts = [q for q in qa if q["answer_struct"]["kind"] in ("points", "region")]
    loc = [q for q in pts if q["family"] in ("locate", "identify")]
    assert len(pts) >= 10 and len(loc) >= 5
    gold = _eval(capsys, d / "out", [{"id": q["id"], "text": _gold(q)} for q in pts], "--variant", "paper")
    moved = _eval(capsys, d / "out", [{"id": q["id"], "text": _move(q, lambda x, y, W, H: (min(x + 60, W - 0.5), y))}
                                      for q in pts], "--variant", "paper")
    frac = len(pts) / len(qa)  # the other QA pairs have no prediction here: 0 in both
    assert gold["components"]["accuracy"]["mean"] == pytest.approx(frac)
    assert moved["components"]["accuracy"]["mean"] < 0.2 * frac
    # x and y swapped: a miss wherever the swap moves the point (off the image diagonal by > 100 px)
    far = [q for q in loc if abs(q["answer_struct"]["points"][0][0] - q["answer_struct"]["points"][0][1]) * q["image_size"][0] > 100]
    assert len(far) >= 5
    swapped = _eval(capsys, d / "out", [{"id": q["id"], "text": _move(q, lambda x, y, W, H: (y / H * W, x / W * H))}
                                        for q in far])
    hits = sum(r["n"] * r["success_rate"] for k, r in swapped["by_family"].items() if k in ("locate", "identify"))
    assert hits <= 0.1 * len(far)
    # reasoning steps in reverse order: the same scores, QA pair by QA pair
    from refspatial_gen.eval.dataset import load_items
    from refspatial_gen.rewards.reward import score

    items = {it.id: it for it in load_items(d / "out")}
    n = 0
    for q in qa:
        if q["trace"] and len(q["key_steps"]) > 1:
            think = q["trace"].split("</think>")[0][len("<think>"):]
            rev = "<think>" + "\n".join(think.split("\n")[::-1]) + "</think>" + q["trace"].split("</think>")[1]
            assert rev != q["trace"]
            assert score(rev, items[q["id"]].gold) == score(q["trace"], items[q["id"]].gold)
            n += 1
    assert n >= 5


def test_prediction_file_problems_are_counted_never_skipped(run, capsys):
    d, qa = run
    p = d / "bad.jsonl"
    rows = [json.dumps({"id": qa[0]["id"], "text": _gold(qa[0])}), "{not json", json.dumps([1, 2]),
            json.dumps({"id": qa[1]["id"]}), json.dumps({"id": "nope", "text": "(A)"}),
            json.dumps({"id": qa[0]["id"], "text": "(B)"}), json.dumps({"id": qa[2]["id"], "text": "gibberish"})]
    p.write_text("\n".join(rows) + "\n")
    capsys.readouterr()
    assert main(["eval", str(d / "out"), "--predictions", str(p), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["problems"] == {"malformed_lines": 3, "unknown_ids": 1, "duplicate_ids": 1, "missing_ids": len(qa) - 2}
    assert s["missing"] == len(qa) - 2 and s["parse_failures"] == 1
    assert s["success_rate"] == pytest.approx(1 / len(qa))  # missing ones count as failures
    assert main(["eval", str(d / "out"), "--predictions", str(p), "--strict"]) == 1
    out, err = capsys.readouterr()
    assert "line 2: malformed: not JSON" in out and "line 5: unknown id 'nope'" in out and "line 6: duplicate id" in out
    assert "malformed_lines=3" in err
    assert main(["eval", str(d / "out"), "--predictions", str(d / "missing.jsonl")]) == 1
    assert "missing.jsonl" in capsys.readouterr().err


def test_baselines_report_and_audit(run, capsys, tmp_path):
    d, qa = run
    rates = {}
    for b in ("gold", "centre", "random", "text-only", "frequent-choice"):
        capsys.readouterr()
        assert main(["eval", str(d / "out"), "--baseline", b, "--json"]) == 0
        rates[b] = json.loads(capsys.readouterr().out)["success_rate"]
    assert rates["gold"] == 1.0 and max(rates["centre"], rates["random"], rates["text-only"]) < 0.6
    assert main(["eval", str(d / "out"), "--audit", "--out", str(tmp_path / "rep")]) == 0
    out = capsys.readouterr().out
    assert "shortcut audit" in out and "placement/" in out
    rep = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert rep["audit"] and all("leaks" in r for r in rep["audit"])
    html = (tmp_path / "rep" / "index.html").read_text()
    assert "Shortcut audit" in html and "by_family.png" in html
    for f in ("by_family.png", "by_steps.png", "components.png"):
        assert (tmp_path / "rep" / f).stat().st_size > 1000


def test_region_masks_agree_with_the_free_space_checker(run):
    from refspatial_gen.core.model import Frame, SceneGraph
    from refspatial_gen.graph.freespace import check_free_point
    from refspatial_gen.rewards.regions import _find, region_mask
    from refspatial_gen.shards.export import iter_dir

    d, _ = run
    rng = np.random.default_rng(0)
    n = 0
    for raw in iter_dir(d / "out"):
        fids = list(raw.header["frame_ids"])
        graphs = {g["frame_id"]: g for g in raw.graphs_json()}
        for q in raw.qa_json():
            if q["answer_struct"]["kind"] != "region":
                continue
            v = fids.index(q["frame_ids"][0])
            fm, dep = raw.frame_meta(v), raw.depth(v)
            m = region_mask(fm, graphs[fm["frame_id"]], q["answer_struct"]["region"], dep)
            frame = Frame.from_meta_json(fm, np.zeros(dep.shape + (3,), np.uint8), dep)
            sg = SceneGraph.from_json(graphs[fm["frame_id"]])
            reg = _find(sg, q["answer_struct"]["region"])
            H, W = dep.shape
            ys, xs = np.nonzero(m)
            assert len(xs), q["qa_id"]
            pix = list(zip(rng.integers(0, W, 20), rng.integers(0, H, 20)))
            pix += [(xs[i], ys[i]) for i in rng.integers(0, len(xs), 20)]
            ys2, xs2 = np.nonzero(~m & (np.abs(np.arange(W)[None, :] - xs.mean()) < 40))  # near the region
            pix += [(xs2[i], ys2[i]) for i in rng.integers(0, len(xs2), 20)] if len(xs2) else []
            for x, y in pix:
                ok = check_free_point(frame, sg, reg, ((x + 0.5) / W, (y + 0.5) / H)) == []
                assert ok == bool(m[y, x]), (q["qa_id"], x, y)
            n += 1
    assert n >= 3


def test_sft_export(run):
    d, qa = run
    out = d / "sft"
    assert main(["export", str(d / "out"), "--format", "sft", "--out", str(out)]) == 0
    idx = json.loads((d / "out" / "index.json").read_text())
    train_pairs = idx["splits"]["counts"]["train"]["qa_pairs"]
    recs = [r for f in out.glob("*.json") for r in json.loads(f.read_text())]
    assert {r["split"] for r in recs} == {"train"} and sum(len(r["conversations"]) // 2 for r in recs) == train_pairs
    traces = {q["trace"] for q in qa if q["trace"]}
    gpt = [t["value"] for r in recs for t in r["conversations"][1::2]]
    reasoning = [v for v in gpt if v.startswith("<think>")]
    assert reasoning and all(v in traces for v in reasoning)
    for r in recs:
        for i, think in enumerate(r.get("think") or []):
            assert r["conversations"][2 * i + 1]["value"] == think["trace"]


def test_rft_export_is_self_contained(run):
    from refspatial_gen.rewards.adapters import compute_score, region_reward_trl

    d, qa = run
    out = d / "rft"
    assert main(["export", str(d / "out"), "--format", "rft", "--split", "train", "--split", "test", "--out", str(out)]) == 0
    lines = [json.loads(x) for x in (out / "rft.jsonl").read_text().splitlines()]
    assert lines and {x["split"] for x in lines} <= {"train", "test"}
    for x in lines:
        assert all((out / "image" / n).is_file() for n in x["images"])
        gt = json.loads(x["reward_model"]["ground_truth"])
        if gt["kind"] in ("points", "region"):
            assert gt["mask"]["counts"]
        r = compute_score(x["data_source"], x["solution"], x["reward_model"]["ground_truth"], x["extra_info"])
        assert r["score"] == 1.0 and r["success"] == 1.0, x["id"]
        assert ("<think>" in x["prompt"][0]["content"]) == bool(gt["reasoning"])
    pts = [x for x in lines if x["answer_struct"]["kind"] in ("points", "region")][:4]
    assert region_reward_trl(prompts=[x["prompt"] for x in pts], completions=[x["solution"] for x in pts],
                             reward_model=[x["reward_model"] for x in pts]) == [1.0] * len(pts)


def test_refspatial_bench_export_follows_the_published_layout(run):
    from PIL import Image

    from refspatial_gen.rewards.parse import parse_points

    d, qa = run
    out = d / "bench"
    assert main(["export", str(d / "out"), "--format", "refspatial-bench", "--split", "test", "--split", "val",
                 "--split", "train", "--out", str(out)]) == 0
    answers = {q["id"]: q["answer"] for q in qa}
    total = 0
    for task in ("Location", "Placement", "Unseen"):
        rows = json.loads((out / task / "question.json").read_text())
        assert [r["id"] for r in rows] == list(range(len(rows)))
        for r in rows:
            assert set(r) == {"id", "object", "prompt", "suffix", "rgb_path", "mask_path", "category", "step", "qa_id"}
            assert r["category"] in ("location", "placement") and 1 <= r["step"] <= 5
            assert "list of tuples" not in r["prompt"] and r["suffix"].startswith("Your answer should be formatted")
            img = Image.open(out / task / r["rgb_path"])
            mask = np.array(Image.open(out / task / r["mask_path"]))
            assert img.mode == "RGB" and mask.dtype == np.uint8 and mask.ndim == 2 and mask.shape == img.size[::-1]
            assert set(np.unique(mask)) <= {0, 255} and mask.any()
            # scored the benchmark's way (summarize_acc: int(x * W), int(y * H) inside mask / 255 > 0)
            W, H = img.size
            (x, y), = [(int(a / W * W), int(b / H * H)) for a, b in parse_points(answers[r["qa_id"]], W, H, "normalized")]
            assert (mask / 255.0)[y, x] > 0
            total += 1
    assert total >= 10
