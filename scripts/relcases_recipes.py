"""Mutated recipes: each must be refused before any work with `file:line: message`, quoting no file.

Mutations are generated from the shipped recipes (every key: a wrong type, NaN / infinity for numbers, an
unknown sibling key, a misspelt key, required keys deleted) plus hand-written hostile ones (paths out
of the recipe's folder, YAML bombs, executable tags, command-line overrides). Each recipe is written to a
temporary folder with a copy of the shipped templates beside it, and checked with `recipes lint` (or
`shards`, for overrides and the output-name cases).
"""

from __future__ import annotations

import copy
import json
import math
import os
import shutil
from pathlib import Path
from typing import Any, Callable

import yaml

from relrun import REPO, Case

RECIPES = sorted(p for p in (REPO / "recipes").glob("*.yaml"))
FREE_FORM = ("families", "layouts", "thresholds")  # mappings whose keys are names the user chooses (a typo is a new name)
REQUIRED = {("sources",), ("sources", 0, "kind"), ("qa", "families")}
MODEL = "models/depth-anything-v2-small"


def _prepare(tmp: Path, data: Any, text: str | None = None) -> Path:
    """The recipe (and a copy of the shipped templates beside it) in `tmp`; returns the recipe path."""
    shutil.copytree(REPO / "recipes" / "templates", tmp / "templates")
    (tmp / MODEL).mkdir(parents=True)
    for name, config in _perception_models(data):  # the local model folders a perception recipe names
        folder = tmp / "models" / name
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "config.json").write_text(json.dumps(config))
    p = tmp / "recipe.yaml"
    if text is None:
        text = yaml.safe_dump(data, sort_keys=False, default_flow_style=False)
    p.write_text(text) if isinstance(text, str) else p.write_bytes(text)
    return p


PERCEPTION_CONFIGS = {  # the config.json a save_pretrained folder of each part's default family holds
    "detector": {"model_type": "grounding-dino"}, "segmenter": {"model_type": "sam"},
    "depth": {"model_type": "depth_anything", "depth_estimation_type": "metric"},
}


def _perception_models(data: Any) -> list[tuple[str, dict]]:
    """(model name, config.json) for each part of a source's `perception:` mapping that names a plain model
    (mutated values of other types are skipped: those mutations must fail on their own)."""
    out: list[tuple[str, dict]] = []
    sources = data.get("sources") if isinstance(data, dict) else None
    for s in sources if isinstance(sources, list) else []:
        cfg = s.get("config") if isinstance(s, dict) else None
        perception = cfg.get("perception") if isinstance(cfg, dict) else None
        for part, config in PERCEPTION_CONFIGS.items():
            sec = perception.get(part) if isinstance(perception, dict) else None
            name = sec.get("model") if isinstance(sec, dict) else None
            if isinstance(name, str) and name and "/" not in name and not name.startswith("."):
                out.append((name, config))
    return out


def _baseline(path: Path) -> dict:
    """The shipped recipe, made valid where it sits in a temporary folder: a model folder beside it, and its
    sim catalogs by absolute path (the built-in catalog when `make assets-*` has not written them)."""
    data = yaml.safe_load(path.read_text())
    for s in data.get("sources", []):
        cfg = s.get("config") or {}
        depth = cfg.get("depth") or {}
        if "model_dir" in depth:
            depth["model_dir"] = MODEL  # a folder that exists beside the recipe (cwd = the recipe's folder)
        if cfg.get("catalog"):
            cats = cfg["catalog"] if isinstance(cfg["catalog"], list) else [cfg["catalog"]]
            full = [str((path.parent / c).resolve()) for c in cats]
            if all(Path(c).is_file() for c in full):
                cfg["catalog"] = full
            else:
                cfg.pop("catalog")
                cfg.pop("external_prob", None)
    return data


def lint_case(group: str, name: str, data: Any = None, text: str | bytes | None = None) -> Case:
    def setup(tmp: Path):
        return ["recipes", "lint", str(_prepare(tmp, data, text))], None
    return Case(group, name, setup, "lint-error", cwd=True)


def _paths(d: Any, prefix: tuple = ()) -> list[tuple]:
    out = []
    if isinstance(d, dict):
        for k, v in d.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            out.append(prefix + (i,))
            out += _paths(v, prefix + (i,))
    return out


def _get(d: Any, path: tuple) -> Any:
    for k in path:
        d = d[k]
    return d


def _with(data: Any, path: tuple, fn: Callable[[Any, Any], None]) -> Any:
    """A deep copy of `data` with fn(parent, key) applied at `path`."""
    d = copy.deepcopy(data)
    fn(_get(d, path[:-1]), path[-1])
    return d


def _set(value: Any) -> Callable[[Any, Any], None]:
    def f(parent, key):
        parent[key] = value
    return f


def _rename(parent: dict, key: Any) -> None:
    items = list(parent.items())
    parent.clear()
    parent.update({(f"{k}x" if k == key else k): v for k, v in items})


def _wrong_type(v: Any) -> Any:
    if isinstance(v, bool) or isinstance(v, (int, float)):
        return "wide"
    if isinstance(v, str):
        return [1, 2]
    if isinstance(v, list):
        return "a list?"
    return [1]  # mapping


def _generated(path: Path) -> list[Case]:
    data = _baseline(path)
    stem = path.stem
    base = lint_case("mutation", f"{stem}: unchanged (the baseline every mutation starts from)", data)
    cases = [Case(base.group, base.name, base.setup, "lint-ok", cwd=True)]
    for p in _paths(data):
        v = _get(data, p)
        where = ".".join(map(str, p))
        is_template = "templates" in p and isinstance(p[-1], int)
        if is_template:
            continue  # template paths get their own cases below
        cases.append(lint_case("mutation", f"{stem}: {where} of the wrong type", _with(data, p, _set(_wrong_type(v)))))
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            cases.append(lint_case("mutation", f"{stem}: {where} = .nan", _with(data, p, _set(math.nan))))
        if isinstance(v, dict) and not (p and p[-1] in FREE_FORM):
            cases.append(lint_case("mutation", f"{stem}: unknown key in {where}",
                                   _with(data, p + ("bogus_key",), _set(1))))
        if isinstance(p[-1], str) and not (len(p) > 1 and p[-2] in FREE_FORM):
            cases.append(lint_case("mutation", f"{stem}: {where} misspelt", _with(data, p, _rename)))
        if tuple(p) in REQUIRED or (len(p) == 4 and p[:2] == ("qa", "families") and p[3] == "templates"):
            cases.append(lint_case("mutation", f"{stem}: required {where} deleted", _with(data, p, lambda d, k: d.pop(k))))
    if isinstance(data, dict):
        cases.append(lint_case("mutation", f"{stem}: unknown top-level key", {**data, "bogus_key": 1}))
    return cases


def _toy(**over: Any) -> dict:
    d = {"name": "t", "seed": 1, "scenes": 2, "sources": [{"kind": "toy"}],
         "qa": {"families": {"locate": {"weight": 1.0, "templates": ["templates/locate.yaml"]}}}}
    d.update(over)
    return d


def _template(path: str) -> dict:
    return _toy(qa={"families": {"locate": {"weight": 1.0, "templates": [path]}}})


def _symlinked(target: str) -> Case:
    def setup(tmp: Path):
        p = _prepare(tmp, _template("templates/evil.yaml"))
        os.symlink(target, tmp / "templates" / "evil.yaml")
        return ["recipes", "lint", str(p)], None
    return Case("paths", f"template symlink to {target}", setup, "lint-error", cwd=True)


PATHS = [
    ("template /etc/passwd", _template("/etc/passwd")),
    ("template /etc/shadow", _template("/etc/shadow")),
    ("template ../../../../etc/passwd", _template("../../../../etc/passwd")),
    ("template ~/.bashrc", _template("~/.bashrc")),
    ("template /dev/zero", _template("/dev/zero")),
    ("template /proc/self/environ", _template("/proc/self/environ")),
    ("template is a folder", _template("templates")),
    ("template does not exist", _template("templates/nope.yaml")),
    ("template path with a NUL byte", _template("templates/a\0b.yaml")),
    ("input: /etc", _toy(sources=[{"kind": "scan", "input": "/etc"}])),
    ("input: ../../../..", _toy(sources=[{"kind": "image", "input": "../../../.."}])),
    ("scan boxes_file: /etc/passwd", _toy(sources=[{"kind": "scan", "input": ".", "config": {"boxes_file": "/etc/passwd"}}])),
    ("sim catalog: /etc/passwd", _toy(sources=[{"kind": "sim", "config": {"catalog": "/etc/passwd"}}])),
    ("image annotations: /etc/passwd", _toy(sources=[{"kind": "image", "input": ".", "config": {"annotations": "/etc/passwd"}}])),
    ("image images_dir: ../../..", _toy(sources=[{"kind": "image", "input": ".", "config": {"images_dir": "../../.."}}])),
    ("depth model_dir: /etc", _toy(sources=[{"kind": "image", "input": ".",
                                             "config": {"depth": {"estimator": "depth-anything", "model_dir": "/etc"}}}])),
    ("depth onnx model_path: /etc/passwd", _toy(sources=[{"kind": "image", "input": ".", "config": {
        "depth": {"estimator": "onnx", "model_path": "/etc/passwd"}}}])),
]

BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 9)}]\n" for i in range(8)) + \
    "name: t\nsources: [{kind: toy}]\n"
YAML = [
    ("billion laughs (9 levels of aliases)", BOMB),
    ("nested 5000 levels deep (flow)", "name: t\nx: " + "[" * 5000 + "]" * 5000 + "\n"),
    ("nested 2000 levels deep (block)", "".join("  " * i + f"k{i}:\n" for i in range(2000)) + "  " * 2000 + "v: 1\n"),
    ("a 5 MB recipe", "name: t\n# " + "x" * (5 * 1024 * 1024) + "\n"),
    ("!!python/object/apply executes nothing", "name: !!python/object/apply:os.system ['touch PWNED']\nsources: []\n"),
    ("!!python/object on a mapping", "name: t\nsources: !!python/object:os.system {}\n"),
    ("!!python/name tag", "name: !!python/name:os.system\nsources: [{kind: toy}]\n"),
    ("!!binary garbage", "name: !!binary '%%%'\nsources: [{kind: toy}]\n"),
    ("!!int that is not a number", "name: t\nseed: !!int abc\nsources: [{kind: toy}]\n"),
    ("tab indentation", "name: t\nsources:\n\t- kind: toy\n"),
    ("duplicate key", "name: t\nname: u\nsources: [{kind: toy}]\n"),
    ("two YAML documents", "name: t\n---\nname: u\n"),
    ("empty file", ""),
    ("comments only", "# nothing here\n"),
    ("top-level list", "- name: t\n"),
    ("top-level scalar", "just words\n"),
    ("unterminated flow", "name: t\nsources: [{kind: toy}\n"),
    ("merge key (<<)", "base: &b {kind: toy}\nname: t\nsources: [{<<: *b}]\n"),
    ("a key that is a list", "[a, b]: 1\nname: t\n"),
    ("a date as the seed", "name: t\nseed: 2024-01-01\nsources: [{kind: toy}]\n"),
    ("a 5000-digit integer", "name: t\nseed: " + "9" * 5000 + "\nsources: [{kind: toy}]\n"),
    ("a 100 kB string value", "name: " + "n" * 100000 + "\nsources: [{kind: toy}]\n"),
]
YAML_BYTES = [
    ("not UTF-8", b"name: \xff\xfe\x00t\nsources: [{kind: toy}]\n"),
    ("a NUL byte", b"name: t\x00\nsources: [{kind: toy}]\n"),
]

SEMANTIC = [
    ("every source weight 0", _toy(sources=[{"kind": "toy", "weight": 0.0}, {"kind": "toy", "weight": 0}])),
    ("source weight NaN", _toy(sources=[{"kind": "toy", "weight": math.nan}])),
    ("source weight -1", _toy(sources=[{"kind": "toy", "weight": -1}])),
    ("source weight infinite", _toy(sources=[{"kind": "toy", "weight": math.inf}])),
    ("scenes 0", _toy(scenes=0)), ("scenes -5", _toy(scenes=-5)), ("scenes 10^15", _toy(scenes=10**15)),
    ("scenes 'many'", _toy(scenes="many")), ("scenes 2.5", _toy(scenes=2.5)),
    ("seed -1", _toy(seed=-1)), ("seed 2^70", _toy(seed=2**70)), ("seed 1.5", _toy(seed=1.5)),
    ("seed true", _toy(seed=True)),
    ("source scenes 0", _toy(sources=[{"kind": "toy", "scenes": 0}])),
    ("sources empty", _toy(sources=[])), ("sources a mapping", _toy(sources={"kind": "toy"})),
    ("unknown source kind", _toy(sources=[{"kind": "lidar"}])),
    ("source config a list", _toy(sources=[{"kind": "scan", "config": [1]}])),
    ("samples_per_shard 0", _toy(shards={"samples_per_shard": 0})),
    ("max_bytes 1", _toy(shards={"max_bytes": 1})), ("image_format gif", _toy(shards={"image_format": "gif"})),
    ("families empty", _toy(qa={"families": {}})),
    ("every family weight 0", _toy(qa={"families": {"locate": {"weight": 0, "templates": ["templates/locate.yaml"]}}})),
    ("family weight NaN", _toy(qa={"families": {"locate": {"weight": math.nan, "templates": ["templates/locate.yaml"]}}})),
    ("family name with a slash", _toy(qa={"families": {"a/b": {"templates": ["templates/locate.yaml"]}}})),
    ("family templates empty", _toy(qa={"families": {"locate": {"templates": []}}})),
    ("family templates a string", _toy(qa={"families": {"locate": {"templates": "templates/locate.yaml"}}})),
    ("qa max_per_sample 99", _toy(qa={"max_per_sample": 99, "families": {
        "locate": {"templates": ["templates/locate.yaml"]}}})),
    ("qa steps {9: 1}", _toy(qa={"steps": {9: 1}, "families": {"locate": {"templates": ["templates/locate.yaml"]}}})),
    ("sim config layouts all 0", _toy(sources=[{"kind": "sim", "config": {"layouts": {"tabletop": 0}}}])),
]


def _shards_case(group: str, name: str, data: dict, extra: list[str], out: bool = True) -> Case:
    def setup(tmp: Path):
        p = _prepare(tmp, data)
        argv = ["shards", "--recipe", str(p), "--workers", "1", "--quiet", "--no-report", *extra]
        if out:
            argv += ["--out", str(tmp / "out")]
        return argv, None
    return Case(group, name, setup, "error", cwd=True)


OVERRIDES = [
    ("--scenes 0", ["--scenes", "0"]), ("--scenes -5", ["--scenes", "-5"]),
    ("--scenes 10^15", ["--scenes", str(10**15)]), ("--seed -1", ["--seed", "-1"]),
    ("--seed 2^70", ["--seed", str(2**70)]), ("--workers 0", ["--workers", "0"]),
    ("--input ''", ["--input", ""]), ("--scenes abc (argparse)", ["--scenes", "abc"]),
]
NAMES = ["../../../x", "/tmp/escape", "..", ".", ".hidden", "a/b", "x" * 300, "na\nme"]


def recipe_cases() -> list[Case]:
    cases: list[Case] = []
    for path in RECIPES:
        cases += _generated(path)
    cases += [lint_case("paths", n, d) for n, d in PATHS]
    cases += [_symlinked(t) for t in ("/etc/passwd", "/etc")]
    cases += [lint_case("yaml", n, text=t) for n, t in YAML + YAML_BYTES]
    cases += [lint_case("recipe", n, d) for n, d in SEMANTIC]
    cases += [_shards_case("overrides", n, _toy(), extra) for n, extra in OVERRIDES]
    cases += [_shards_case("paths", f"name {n!r} without --out", _toy(name=n), [], out=False) for n in NAMES]
    return cases
