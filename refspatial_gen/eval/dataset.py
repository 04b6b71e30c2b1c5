"""The evaluation set of a shard directory: every QA pair with its ground truth (`Gold`) and what the
report groups by (family, template, relations, step count, source, split).

Ids are the QA ids of the JSON-lines export (`export --format jsonl`: `id` = `qa_id`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from refspatial_gen.rewards.gold import Gold, build_gold, gold_text


@dataclass
class Item:
    id: str
    gold: Gold
    family: str
    template: str
    relations: list[str]
    steps: int
    source: str
    split: str
    sample_id: str
    question: str
    gold_text: str


def load_items(shard_dir: Path | str, splits: Iterable[str] | None = None) -> list[Item]:
    """Every QA pair of the dataset (or of the given splits), in index order. Raises ValueError when a QA
    id repeats (ids must name one QA pair) or a ground truth cannot be built."""
    from refspatial_gen.run.splits import sample_split, scene_splits
    from refspatial_gen.shards.export import iter_dir
    from refspatial_gen.shards.index import read_index

    d = Path(shard_dir)
    scene_map = scene_splits(read_index(d))
    wanted = None if splits is None else set(splits)
    items: list[Item] = []
    seen: set[str] = set()
    for raw in iter_dir(d):
        h = raw.header
        frame_ids = list(h["frame_ids"])
        metas = [raw.frame_meta(v) for v in range(int(h["views"]))]
        split = sample_split(scene_map, metas, h["sample_id"])
        if wanted is not None and split not in wanted:
            continue
        graphs = {g["frame_id"]: g for g in raw.graphs_json()}
        depths: dict[int, object] = {}
        for qa in raw.qa_json():
            if qa["qa_id"] in seen:
                raise ValueError(f"{d}: QA id {qa['qa_id']!r} appears twice; ids must be unique to evaluate")
            seen.add(qa["qa_id"])
            v = frame_ids.index(qa["frame_ids"][0]) if qa["frame_ids"] and qa["frame_ids"][0] in frame_ids else 0
            if (qa.get("answer_struct") or {}).get("kind") == "region" and v not in depths:
                depths[v] = raw.depth(v)
            gold = build_gold(qa, metas[v], graphs.get(metas[v]["frame_id"]), depths.get(v))
            items.append(
                Item(
                    id=qa["qa_id"],
                    gold=gold,
                    family=qa["family"],
                    template=qa["template"],
                    relations=list(qa.get("relations") or []),
                    steps=int(qa["steps"]),
                    source=str(metas[v].get("source", "?")),
                    split=split,
                    sample_id=h["sample_id"],
                    question=qa["question"],
                    gold_text=gold_text(qa),
                )
            )
    return items
