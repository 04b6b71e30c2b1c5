"""A stratified, seeded sample of QA pairs over one or more datasets, for judging by eye.

Why stratified: a plain random sample of a default run is mostly one source and the commonest families,
so the rare strata (5-step questions, photos, scans) go unjudged. The sample spreads over
(dataset label, family, step count): every dataset gets at least `min_per_label` items (or all it has),
and within a dataset the items are spread round-robin over its (family, steps) strata, so rare strata
are represented before common ones get a second item. Same datasets + seed -> the same sample.
Sampling reads only the shards' metadata; pixels are decoded later, only for the picked items.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Item:
    """One QA pair picked for review; `item_id` is unique over the audit (`label/qa_id`)."""

    label: str  # the dataset's label (e.g. "sim", "ycb", "scan", "photos"); several folders may share one
    part: int  # which folder of that label (0, 1, ... in the order given)
    shard: str  # shard file name inside the dataset folder
    seq: int  # the sample's sequence number inside the shard
    sample_id: str
    qa_index: int
    qa_id: str
    family: str
    steps: int
    source: str  # the frames' source kind (sim / scan / image ...)

    @property
    def item_id(self) -> str:
        return f"{self.label}/{self.part}/{self.qa_id}"

    @property
    def stratum(self) -> tuple[str, str, int]:
        return (self.label, self.family, self.steps)

    def to_json(self) -> dict[str, Any]:
        return {
            "item_id": self.item_id,
            "label": self.label,
            "part": self.part,
            "shard": self.shard,
            "seq": self.seq,
            "sample_id": self.sample_id,
            "qa_index": self.qa_index,
            "qa_id": self.qa_id,
            "family": self.family,
            "steps": self.steps,
            "source": self.source,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Item:
        return cls(
            d["label"],
            int(d["part"]),
            d["shard"],
            int(d["seq"]),
            d["sample_id"],
            int(d["qa_index"]),
            d["qa_id"],
            d["family"],
            int(d["steps"]),
            d["source"],
        )


def parse_dataset_args(args: list[str]) -> list[tuple[str, Path]]:
    """`LABEL=DIR` or `DIR` (label = the folder's name) -> [(label, folder)]. Several folders may share a
    label (e.g. two scan datasets judged as one stratum); the same folder may not be given twice."""
    out: list[tuple[str, Path]] = []
    for a in args:
        label, sep, d = a.partition("=")
        if not sep:
            label, d = Path(a).resolve().name, a
        if not label or "/" in label:
            raise ValueError(f"{a}: a dataset label must be a non-empty word without '/'")
        if any(Path(d).resolve() == Path(x).resolve() for _, x in out):
            raise ValueError(f"{a}: folder given twice")
        out.append((label, Path(d)))
    return out


def parts(pairs: list[tuple[str, Path]]) -> list[tuple[str, int, Path]]:
    """(label, part number within the label, folder) for each dataset argument."""
    seen: dict[str, int] = {}
    out = []
    for label, d in pairs:
        out.append((label, seen.get(label, 0), d))
        seen[label] = seen.get(label, 0) + 1
    return out


def candidates(label: str, part: int, folder: Path) -> list[Item]:
    """Every QA pair of a dataset folder (shards listed in its index.json), metadata only."""
    from refspatial_gen.shards.index import read_index
    from refspatial_gen.shards.reader import read_sample_meta

    index = read_index(folder)
    out: list[Item] = []
    for row in index["shards"]:
        for m in read_sample_meta(folder / row["name"]):
            src = (m.get("frames") or [{}])[0].get("source", "?")
            for qi, q in enumerate(m["qa"]):
                out.append(
                    Item(
                        label,
                        part,
                        row["name"],
                        int(m["seq"]),
                        m["sample_id"],
                        qi,
                        q["qa_id"],
                        q["family"],
                        int(q["steps"]),
                        src,
                    )
                )
    return out


def stratified(items_by_label: dict[str, list[Item]], n: int, seed: int, min_per_label: int) -> list[Item]:
    """`n` items (fewer if the datasets hold fewer): first `min_per_label` from each dataset, then the rest
    shared out one at a time to the dataset with the fewest picks so far; within a dataset, items are drawn
    round-robin over its (family, steps) strata in a seeded order. Sorted by item id for a stable page."""
    rng = np.random.default_rng(seed)
    queues: dict[str, list[Item]] = {}
    for label in sorted(items_by_label):
        queues[label] = _round_robin(items_by_label[label], rng)
    taken: dict[str, int] = {lab: 0 for lab in queues}
    picked: list[Item] = []

    def take(label: str) -> bool:
        q = queues[label]
        if taken[label] >= len(q):
            return False
        picked.append(q[taken[label]])
        taken[label] += 1
        return True

    for label in queues:
        for _ in range(min_per_label):
            if len(picked) >= n or not take(label):
                break
    while len(picked) < n:
        open_labels = [lab for lab in queues if taken[lab] < len(queues[lab])]
        if not open_labels:
            break
        take(min(open_labels, key=lambda lab: (taken[lab], lab)))
    return sorted(picked, key=lambda it: (it.label, it.family, it.steps, it.item_id))


def _round_robin(items: list[Item], rng: np.random.Generator) -> list[Item]:
    """Items ordered so that every (family, steps) stratum appears once before any appears twice."""
    strata: dict[tuple[str, int], list[Item]] = {}
    for it in sorted(items, key=lambda i: i.item_id):
        strata.setdefault((it.family, it.steps), []).append(it)
    keys = sorted(strata)
    order = [keys[i] for i in rng.permutation(len(keys))]
    shuffled = {k: [strata[k][i] for i in rng.permutation(len(strata[k]))] for k in order}
    out: list[Item] = []
    depth = 0
    while len(out) < len(items):
        for k in order:
            if depth < len(shuffled[k]):
                out.append(shuffled[k][depth])
        depth += 1
    return out
