"""Splits: by scene group, never by QA pair; unseen holds out categories and (category, relation) pairs; recipe errors."""

from pathlib import Path

import pytest

from refspatial_gen.core.errors import RecipeErrors
from refspatial_gen.run.splits import SPLITS, assign, default_config, sample_keys, scene_splits

TOY_HEAD = "name: t\nsources:\n  - kind: toy\n"


def _meta(sid, scenes, cats=("cup",), qa=()):
    frames = [{"frame_id": f"{sid}/v{i}", "scene_id": s, "objects": [{"id": j + 1, "category": c} for j, c in enumerate(cats)]}
              for i, s in enumerate(scenes)]
    return {"sample_id": sid, "frames": frames, "qa": list(qa)}


def _qa(fid, rel, target, anchor=None):
    prog = [{"op": "relate", "args": {"anchor": {"object": anchor, "phrase": "x"}}}] if anchor else []
    return {"frame_ids": [fid], "relations": [rel], "targets": [target], "program": prog}


def _cfg(**unseen):
    c = default_config()
    c["unseen"] = {"categories": unseen.get("categories", []), "combinations": unseen.get("combinations", [])}
    return c


def test_scene_groups_never_straddle_splits_and_counts_add_up():
    cfg = _cfg()
    metas = [_meta(f"s{i}", [f"scene{i // 3}"]) for i in range(60)]  # three samples per scene
    metas.append(_meta("mv", ["scene0", "scene19"]))  # a sample joining two scenes: one group
    sec = assign([sample_keys(m, cfg) for m in metas], cfg)
    where = {}
    for name, scenes in sec["scenes"].items():
        for s in scenes:
            assert s not in where, f"{s} in {where.get(s)} and {name}"
            where[s] = name
    assert len(where) == 20 and where["scene0"] == where["scene19"]
    assert sum(c["samples"] for c in sec["counts"].values()) == 61
    assert sec["counts"]["test"]["scenes"] >= 1 and sec["counts"]["val"]["scenes"] >= 1
    assert scene_splits({"splits": sec}) == where
    # deterministic, and the salt changes the draw
    assert assign([sample_keys(m, cfg) for m in metas], cfg) == sec
    other = dict(cfg, salt="other")
    assert assign([sample_keys(m, other) for m in metas], other)["scenes"] != sec["scenes"]


def test_unseen_holds_out_categories_and_combinations():
    cfg = _cfg(categories=["teddy bear"], combinations=[{"category": "cup", "relation": "left"}])
    metas = [
        _meta("a", ["A"], cats=("teddy bear", "cup")),  # shows a held-out category
        _meta("b", ["B"], cats=("cup", "bowl"), qa=[_qa("b/v0", "left", 2, anchor=1)]),  # left of the cup (anchor)
        _meta("c", ["C"], cats=("cup", "bowl"), qa=[_qa("c/v0", "right", 1, anchor=2)]),  # cup, but not "left"
        _meta("d", ["D"], cats=("bowl", "plate"), qa=[_qa("d/v0", "left", 1, anchor=2)]),  # left, but no cup
        _meta("a2", ["A"], cats=("bowl",)),  # same scene as "a": follows it into unseen
    ]
    sec = assign([sample_keys(m, cfg) for m in metas], cfg)
    assert sec["scenes"]["unseen"] == ["A", "B"]
    assert sec["unseen_reasons"] == {"category:teddy bear": 1, "combination:cup|left": 1}
    assert sec["counts"]["unseen"] == {"scenes": 2, "samples": 3, "qa_pairs": 1}
    assert set(sec["scenes"]) == set(SPLITS)


def test_recipe_section_validated(tmp_path):
    from refspatial_gen.recipe import load_recipe

    p = tmp_path / "r.yaml"
    p.write_text(TOY_HEAD + "splits:\n  fractions: {train: 0.5, tset: 0.5}\n  unseen:\n    categories: [mug]\n"
                 "    combinations:\n      - {category: cup, relation: leftish}\n      - {category: cup}\n")
    with pytest.raises(RecipeErrors) as e:
        load_recipe(p)
    msgs = [str(x) for x in e.value.errors]
    assert any("r.yaml:5" in m and "tset" in m for m in msgs), msgs
    assert any("r.yaml:9" in m and "leftish" in m for m in msgs), msgs
    assert any("r.yaml:10" in m and "relation" in m for m in msgs), msgs
    tpl = Path(__file__).resolve().parents[1] / "recipes" / "templates" / "locate.yaml"
    p.write_text(TOY_HEAD + f"qa:\n  families:\n    locate: {{templates: [{tpl}]}}\n"
                 "splits:\n  unseen:\n    combinations:\n      - {category: cup, relation: left}\n")
    r = load_recipe(p)
    assert r.splits["fractions"] == {"train": 0.8, "val": 0.1, "test": 0.1}
    assert r.splits["unseen"]["combinations"] == [{"category": "cup", "relation": "left"}]
