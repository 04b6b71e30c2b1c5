"""`export --format rft`: one self-contained JSON line per QA pair for reinforcement fine-tuning.

OUT/
  rft.jsonl     one line per QA pair (below)
  image/        the stored RGB bytes, copied (names as in the jsonl/refspatial exports)

Each line:
  id, sample_id, split, family, template, steps, relations, source, images [names], image_size [W, H],
  prompt        [{"role": "user", "content": question}] (+ the reasoning-format instruction for QA pairs
                with a gold trace), the conversational form TRL and verl read
  question, answer, solution (what a perfect model writes: the trace, else the answer), key_steps,
  answer_struct
  data_source   "refspatial-gen/<family>"
  reward_model  {"style": "rule", "ground_truth": <the Gold JSON string: answer, key steps, image size and
                the target mask / free-space region mask as RLE>} (verl's layout; the TRL adapters read it too)
  extra_info    {"qa_id", "split", "family"}
Only the requested splits are written (default: train; a dataset whose index has no splits is written whole).
Image names come from export_files.StemRegistry (two ids that look alike once made file-safe still get
two files) and every file is created once (write_new); `check_export` compares every line's images with
the shards, and `shards.export` writes the whole folder atomically.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from refspatial_gen.rewards.gold import build_gold, gold_text
from refspatial_gen.run.splits import keep_sample, sample_split, splits_of_samples
from refspatial_gen.shards.export_files import (
    EXT,
    StemRegistry,
    check_image_refs,
    stored_image_hashes,
    view_name,
    write_new,
)
from refspatial_gen.shards.format import RawSample

REASONING_INSTRUCTION = (
    "Output the thinking process in <think> </think> and the final answer in <answer> </answer> tags."
)


def rft_lines(raw: RawSample, names: list[str], split: str) -> list[dict]:
    """The RFT lines of one sample (masks of free-space answers need the depth map: decoded here)."""
    h = raw.header
    frame_ids = list(h["frame_ids"])
    graphs = {g["frame_id"]: g for g in raw.graphs_json()}
    metas: dict[int, dict] = {}
    depths: dict[int, object] = {}
    out = []
    for qa in raw.qa_json():
        vs = [frame_ids.index(f) for f in qa["frame_ids"] if f in frame_ids] or [0]
        v = vs[0]
        if v not in metas:
            metas[v] = raw.frame_meta(v)
        kind = (qa.get("answer_struct") or {}).get("kind")
        if kind == "region" and v not in depths:
            depths[v] = raw.depth(v)
        gold = build_gold(qa, metas[v], graphs.get(metas[v]["frame_id"]), depths.get(v))
        content = qa["question"] + (" " + REASONING_INSTRUCTION if gold.reasoning else "")
        out.append(
            {
                "id": qa["qa_id"],
                "sample_id": h["sample_id"],
                "split": split,
                "family": qa["family"],
                "template": qa["template"],
                "steps": qa["steps"],
                "relations": qa["relations"],
                "source": metas[v].get("source"),
                "images": [names[i] for i in vs],
                "image_size": qa["image_size"],
                "prompt": [{"role": "user", "content": content}],
                "question": qa["question"],
                "answer": qa["answer"],
                "solution": gold_text(qa),
                "key_steps": qa.get("key_steps") or [],
                "answer_struct": qa["answer_struct"],
                "data_source": f"refspatial-gen/{qa['family']}",
                "reward_model": {"style": "rule", "ground_truth": gold.dumps()},
                "extra_info": {"qa_id": qa["qa_id"], "split": split, "family": qa["family"]},
            }
        )
    return out


def export_rft(raws: Iterable[RawSample], out: Path | str, *, splits: Iterable[str] | None = ("train",)) -> dict:
    """Write `out/rft.jsonl` and `out/image/`; returns {"qa_pairs", "samples", "by_split", "by_family"}."""
    out = Path(out)
    (out / "image").mkdir(parents=True, exist_ok=True)
    scene_map = splits_of_samples(raws)
    wanted = None if splits is None else tuple(splits)
    n = m = 0
    by_split: dict[str, int] = {}
    by_family: dict[str, int] = {}
    stems = StemRegistry()
    with open(out / "rft.jsonl", "x", encoding="utf-8") as f:
        for raw in raws:
            h = raw.header
            views = int(h["views"])
            split = sample_split(scene_map, [raw.frame_meta(v) for v in range(views)], h["sample_id"])
            if not keep_sample(split, wanted):
                continue
            base = stems.claim(h["sample_id"])
            names = []
            for v in range(views):
                data, fmt = raw.image_bytes(v)
                names.append(view_name(base, v, EXT.get(fmt, fmt)))
                write_new(out / "image" / names[-1], data)
            for line in rft_lines(raw, names, split):
                f.write(json.dumps(line, ensure_ascii=False, sort_keys=True) + "\n")
                n += 1
                by_split[split] = by_split.get(split, 0) + 1
                by_family[line["family"]] = by_family.get(line["family"], 0) + 1
            m += 1
    return {
        "qa_pairs": n,
        "samples": m,
        "by_split": dict(sorted(by_split.items())),
        "by_family": dict(sorted(by_family.items())),
    }


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """Every line parses, belongs to a sample of the shards and names images holding exactly the bytes
    the shards store for that sample's views; no QA id appears twice."""
    out = Path(out)
    stored = stored_image_hashes(raws)
    samples = {who[0] for _, who in stored.values()}
    refs: list[str] = []
    problems: list[str] = []
    seen: set[str] = set()
    path = out / "rft.jsonl"
    for i, text in enumerate(path.read_text(encoding="utf-8").splitlines()):
        try:
            line = json.loads(text)
            qid, sid, images = line["id"], line["sample_id"], list(line["images"])
        except (ValueError, KeyError, TypeError) as e:
            problems.append(f"{path}:{i + 1}: not an RFT line ({e})")
            continue
        if qid in seen:
            problems.append(f"{path}:{i + 1}: QA id {qid!r} appears twice")
        seen.add(qid)
        if sid not in samples:
            problems.append(f"{path}:{i + 1}: sample {sid!r} is not in the shards")
        for name in images:
            if stored.get(name, ("", (None, 0)))[1][0] != sid:
                problems.append(f"{path}:{i + 1}: image {name} is not a view of sample {sid!r}")
        refs += images
    return problems + check_image_refs(out / "image", refs, stored, str(path))
