"""Dataset splits that test generalisation: train / val / test by scene, and an `unseen` split.

Recipe section (all optional; these are the defaults):

    splits:
      fractions: {train: 0.8, val: 0.1, test: 0.1}
      salt: refspatial-gen          # change it to draw another assignment
      unseen:
        categories: [teddy bear]    # scenes showing an object of these categories
        combinations:               # scenes with a QA pair asking this relation about this category
          - {category: cup, relation: left}

Rule (recorded in index.json under `splits`, with the config, counts and every scene's split):
1. Scenes are `Frame.scene_id`s; scenes that share a sample are one group (a group never straddles splits).
2. A group goes to `unseen` when any of its samples shows a held-out category, or has a QA pair whose
   relations include a held-out relation while one of the objects it names (targets and anchors) has
   the paired category. So no train/val/test scene ever shows a held-out category or asks a held-out
   combination.
3. The other groups are ordered by sha256(salt, group key) and cut into train / val / test with the
   fractions (largest remainder, so small datasets still get a test split).
Never by QA pair: every QA pair of a scene is in the scene's split.

Why at index time: step 1 and 2 need every sample of a scene, which one worker never sees; the pass reads
only sample metadata (no pixels), and depends only on shard contents, so the index stays byte-identical
for any worker count.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.schema import Field, check_section
from refspatial_gen.yamlpos import line_of

SPLITS = ("train", "val", "test", "unseen")
DEFAULT_FRACTIONS = {"train": 0.8, "val": 0.1, "test": 0.1}
DEFAULT_SALT = "refspatial-gen"
RULE = (
    "scenes sharing a sample form a group; a group with a held-out category or (category, relation) "
    "goes to unseen; the others are ordered by sha256(salt NUL group) and cut by the fractions "
    "(largest remainder)"
)

SPLIT_FIELDS = {
    "fractions": Field(dict, default=None, doc="share of scenes per split: train, val, test"),
    "salt": Field(str, default=DEFAULT_SALT, doc="hash salt of the scene assignment"),
    "unseen": Field(dict, default=None, doc="held-out categories and (category, relation) combinations"),
}
UNSEEN_FIELDS = {
    "categories": Field(list, default=None, doc="object categories never shown in train/val/test scenes"),
    "combinations": Field(list, default=None, doc="[{category, relation}] never asked in train/val/test scenes"),
}
COMBO_FIELDS = {"category": Field(str, required=True), "relation": Field(str, required=True)}


def default_config() -> dict[str, Any]:
    return {
        "fractions": dict(DEFAULT_FRACTIONS),
        "salt": DEFAULT_SALT,
        "unseen": {"categories": [], "combinations": []},
    }


def check_splits(data: Any, file: str, lines: dict, errors: list[RecipeError]) -> dict[str, Any]:
    """Validate the recipe's `splits:` section (every problem appended to `errors`); the config with defaults."""
    top = check_section(data, SPLIT_FIELDS, file, lines, ("splits",), errors)
    cfg = default_config()
    cfg["salt"] = top["salt"]
    if top["fractions"] is not None:
        fr = {}
        for k, v in top["fractions"].items():
            ln = line_of(lines, ("splits", "fractions", k))
            if k not in DEFAULT_FRACTIONS:
                errors.append(RecipeError(file, ln, f"splits.fractions: unknown split {k!r} (known: train, val, test)"))
            elif isinstance(v, bool) or not isinstance(v, (int, float)) or v < 0:
                errors.append(RecipeError(file, ln, f"splits.fractions.{k} must be a number >= 0, got {v!r}"))
            else:
                fr[k] = float(v)
        if fr and sum(fr.values()) <= 0:
            errors.append(RecipeError(file, line_of(lines, ("splits", "fractions")), "splits.fractions sum to zero"))
        cfg["fractions"] = {k: fr.get(k, 0.0) for k in DEFAULT_FRACTIONS}
    un = check_section(top["unseen"], UNSEEN_FIELDS, file, lines, ("splits", "unseen"), errors)
    cats = []
    for i, c in enumerate(un["categories"] or []):
        if not isinstance(c, str) or not c.strip():
            errors.append(
                RecipeError(
                    file,
                    line_of(lines, ("splits", "unseen", "categories", i)),
                    f"splits.unseen.categories[{i}] must be a category name, got {c!r}",
                )
            )
        else:
            cats.append(c.strip())
    known = _relation_ids()
    combos = []
    for i, c in enumerate(un["combinations"] or []):
        path = ("splits", "unseen", "combinations", i)
        d = check_section(c, COMBO_FIELDS, file, lines, path, errors)
        if d["relation"] is not None and d["relation"] not in known:
            errors.append(
                RecipeError(
                    file,
                    line_of(lines, path + ("relation",)),
                    f"unknown relation {d['relation']!r} (see `refspatial-gen relations`)",
                )
            )
        elif d["category"] is not None and d["relation"] is not None:
            combos.append({"category": d["category"], "relation": d["relation"]})
    cfg["unseen"] = {
        "categories": sorted(set(cats)),
        "combinations": sorted({(c["category"], c["relation"]) for c in combos}),
    }
    cfg["unseen"]["combinations"] = [{"category": a, "relation": b} for a, b in cfg["unseen"]["combinations"]]
    return cfg


def _relation_ids() -> set[str]:
    from refspatial_gen.graph.relations import listing

    return {r["id"] for r in listing()}


# ----------------------------------------------------------------------------- per-sample keys
def _objects_named(qa: dict) -> set[int]:
    """Ids of the objects a QA pair names: its targets and every {"object": id} in its program."""
    out = {int(t) for t in qa.get("targets") or []}
    stack: list[Any] = [qa.get("program") or []]
    while stack:
        x = stack.pop()
        if isinstance(x, dict):
            if isinstance(x.get("object"), int):
                out.add(x["object"])
            stack.extend(x.values())
        elif isinstance(x, list):
            stack.extend(x)
    return out


def sample_keys(meta: dict, cfg: dict) -> dict[str, Any]:
    """What the assignment needs from one sample (`read_sample_meta` dict): scenes, QA count, unseen hits."""
    frames = meta["frames"]
    scenes = scene_ids(frames, meta["sample_id"])
    held_cats = set(cfg["unseen"]["categories"])
    held_combos = {(c["category"], c["relation"]) for c in cfg["unseen"]["combinations"]}
    hits = {f"category:{o['category']}" for f in frames for o in f["objects"] if o["category"] in held_cats}
    if held_combos:
        cats_by_frame = {f["frame_id"]: {o["id"]: o["category"] for o in f["objects"]} for f in frames}
        for qa in meta["qa"]:
            cats = cats_by_frame.get((qa.get("frame_ids") or [frames[0]["frame_id"]])[0], {})
            named = {cats[i] for i in _objects_named(qa) if i in cats}
            for rel in qa.get("relations") or []:
                for c in named:
                    if (c, rel) in held_combos:
                        hits.add(f"combination:{c}|{rel}")
    return {"sample_id": meta["sample_id"], "scenes": scenes, "qa_pairs": len(meta["qa"]), "unseen": sorted(hits)}


# ----------------------------------------------------------------------------- assignment
def assign(keys: Iterable[dict], cfg: dict) -> dict[str, Any]:
    """The `splits` section of index.json from every sample's `sample_keys`."""
    from refspatial_gen.run.plan import split_by_weight

    keys = list(keys)
    parent: dict[str, str] = {}

    def find(a: str) -> str:
        while parent.setdefault(a, a) != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for k in keys:
        for s in k["scenes"][1:]:
            ra, rb = find(k["scenes"][0]), find(s)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
        find(k["scenes"][0])
    groups: dict[str, set[str]] = {}
    for s in list(parent):
        groups.setdefault(find(s), set()).add(s)
    unseen_reasons: dict[str, set[str]] = {}
    unseen_groups = set()
    for k in keys:
        for h in k["unseen"]:
            g = find(k["scenes"][0])
            unseen_groups.add(g)
            unseen_reasons.setdefault(h, set()).add(g)
    salt = cfg["salt"]
    rest = sorted(
        (g for g in groups if g not in unseen_groups),
        key=lambda g: (hashlib.sha256(f"{salt}\0{g}".encode()).hexdigest(), g),
    )
    names = ("test", "val", "train")
    fr = cfg["fractions"]
    counts = split_by_weight(len(rest), [fr["test"], fr["val"], fr["train"]]) if rest else [0, 0, 0]
    split_of_group = {g: "unseen" for g in unseen_groups}
    pos = 0
    for name, n in zip(names, counts):
        for g in rest[pos : pos + n]:
            split_of_group[g] = name
        pos += n
    scene_split = {s: split_of_group[g] for g, members in groups.items() for s in members}
    totals = {name: {"scenes": 0, "samples": 0, "qa_pairs": 0} for name in SPLITS}
    for name in scene_split.values():
        totals[name]["scenes"] += 1
    for k in keys:
        name = scene_split[k["scenes"][0]]
        totals[name]["samples"] += 1
        totals[name]["qa_pairs"] += k["qa_pairs"]
    return {
        "rule": RULE,
        "config": cfg,
        "counts": totals,
        "unseen_reasons": {h: len(gs) for h, gs in sorted(unseen_reasons.items())},
        "scenes": {name: sorted(s for s, n in scene_split.items() if n == name) for name in SPLITS},
    }


def index_section(recipe, out_dir: Path, shards: list[dict]) -> dict[str, Any]:
    """`{"splits": ...}` for index.json, from the finished shards' sample metadata (the executor's hook)."""
    from refspatial_gen.shards.reader import read_sample_meta

    cfg = getattr(recipe, "splits", None) or default_config()
    keys = [
        sample_keys(m, cfg)
        for s in sorted(shards, key=lambda s: s["name"])
        for m in read_sample_meta(Path(out_dir) / s["name"])
    ]
    return {"splits": assign(keys, cfg)}


# ----------------------------------------------------------------------------- readers
def scene_splits(index: dict) -> dict[str, str]:
    """scene id -> split, from an index.json (empty when the index predates splits)."""
    sec = index.get("splits") or {}
    return {s: name for name, scenes in (sec.get("scenes") or {}).items() for s in scenes}


def scene_ids(frames: list[dict], sample_id: str) -> list[str]:
    """A sample's scene ids as the assignment sees them (frame meta dicts; the sample id if none is set)."""
    return sorted({f.get("scene_id") or sample_id for f in frames})


def sample_split(scene_map: dict[str, str], frames: list[dict], sample_id: str) -> str:
    """The split of a sample ("unassigned" when the index has no splits)."""
    for s in scene_ids(frames, sample_id):
        if s in scene_map:
            return scene_map[s]
    return "unassigned"


def splits_of_samples(samples) -> dict[str, str]:
    """scene id -> split for an exporter's samples (`shards.export.DirSamples` carries its folder); {} if unknown."""
    d = getattr(samples, "shard_dir", None)
    if d is None:
        return {}
    from refspatial_gen.shards.index import read_index

    return scene_splits(read_index(d))


def keep_sample(split: str, wanted: Iterable[str] | None) -> bool:
    """Export filter: `wanted` None keeps all; a dataset without splits ("unassigned") is always kept."""
    return wanted is None or split == "unassigned" or split in set(wanted)
