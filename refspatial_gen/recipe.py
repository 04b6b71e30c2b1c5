"""Recipes: the YAML that fully describes a dataset (sources and their mix, graph and QA options, shards).

Every error in a recipe (and in the template files it points to) is found here, before any work starts,
and reported as `file:line: message`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.core.serialize import dumps
from refspatial_gen.graph.config import check_graph_section
from refspatial_gen.qa.config import load_qa_config
from refspatial_gen.recipe_paths import Confinement, check_name, check_rewrite, check_source_config, check_templates
from refspatial_gen.rewrite.config import load_rewrite_config
from refspatial_gen.run.splits import check_splits
from refspatial_gen.schema import Field, check_section, non_finite
from refspatial_gen.sources import get_source, source_names
from refspatial_gen.yamlpos import line_of, load_yaml

# A plan holds one small record per unit in memory; past this, split the dataset into runs with other seeds.
MAX_SCENES = 1_000_000
MAX_SEED = 2**64 - 1

TOP_FIELDS: dict[str, Field] = {
    "name": Field(str, check=check_name, doc="dataset name (a folder name under out/shards)"),
    "description": Field(str, default=""),
    "seed": Field(
        int, default=0, min=0, max=MAX_SEED, doc="run seed; every unit derives its generator from (seed, unit id)"
    ),
    "scenes": Field(int, default=100, min=1, max=MAX_SCENES, doc="units to generate, split across sources by weight"),
    "sources": Field(list, required=True),
    "graph": Field(dict, default=None),
    "qa": Field(dict, default=None),
    "shards": Field(dict, default=None),
    "splits": Field(dict, default=None, doc="train/val/test fractions and the unseen split (run/splits.py)"),
    "rewrite": Field(dict, default=None, doc="LLM rewriting of questions (docs/rewrite.md)"),
}

SOURCE_FIELDS: dict[str, Field] = {
    "kind": Field(str, required=True, doc="registered source name"),
    "weight": Field(float, default=1.0, min=0.0),
    "scenes": Field(
        int, default=None, min=1, max=MAX_SCENES, doc="fixed unit count for this source (overrides the weight split)"
    ),
    "input": Field(str, default=None, doc="input folder (scan/image sources), relative to the recipe file"),
    "config": Field(dict, default=None),
}

SHARD_FIELDS: dict[str, Field] = {
    "samples_per_shard": Field(int, default=16, min=1, max=100000),
    "max_bytes": Field(int, default=512 * 1024 * 1024, min=1024),
    "image_format": Field(str, default="jpeg", choices=("jpeg", "png")),
}


@dataclass
class SourceSpec:
    index: int
    kind: str
    weight: float
    scenes: int | None
    input: str | None
    config: dict[str, Any]


@dataclass
class Recipe:
    path: str
    name: str
    seed: int
    scenes: int
    sources: list[SourceSpec]
    graph: dict[str, Any]
    qa: Any  # compiled QA configuration (refspatial_gen.qa.load_qa_config)
    shards: dict[str, Any]
    hash: str  # sha256 over the recipe text and every file it depends on (templates)
    raw: dict[str, Any] = field(default_factory=dict)
    splits: dict[str, Any] = field(default_factory=dict)  # run/splits.py config, recorded in index.json
    rewrite: Any = None  # compiled `rewrite:` section (refspatial_gen.rewrite.config), None when absent or off


def _source_config(
    kind: str,
    data: Any,
    file: str,
    lines: dict,
    path: tuple,
    errors: list[RecipeError],
    conf: Confinement,
    inp: str | None,
) -> dict:
    """The source's validated config; its paths are confined before the source's own hook may open them."""
    src = get_source(kind)
    fields = getattr(src, "CONFIG_FIELDS", None)
    if fields is None:
        if data is not None and not isinstance(data, dict):
            errors.append(RecipeError(file, line_of(lines, path), "config must be a mapping"))
            return {}
        cfg = dict(data or {})
        check_source_config(kind, cfg, path[1], inp, conf)
        return cfg
    n = len(errors)
    cfg = check_section(data, fields, file, lines, path, errors)
    check_source_config(kind, cfg, path[1], inp, conf)
    hook = getattr(src, "check_config", None)  # source checks that need the recipe's folder (paths) or files
    if hook is not None and len(errors) == n:
        hook(cfg, file, lines, path, errors)
    return cfg


class OverrideError(RecipeError):
    """A command-line override that fails the recipe's own check: printed `--scenes: message`."""

    def __str__(self) -> str:
        return f"{self.file}: {self.message}"


def check_overrides(seed: int | None, scenes: int | None) -> None:
    """`--seed` / `--scenes` go through the same fields (type, range) as the recipe's `seed:` / `scenes:`."""
    errors: list[RecipeError] = []
    for flag, key, value in (("--seed", "seed", seed), ("--scenes", "scenes", scenes)):
        if value is None:
            continue
        errs: list[RecipeError] = []
        check_section({key: value}, {key: TOP_FIELDS[key]}, flag, {}, (), errs)
        errors += [OverrideError(flag, None, e.message.removeprefix(f"{key} ")) for e in errs]
    if errors:
        raise RecipeErrors(errors)


def _sources(
    top: dict, file: str, lines: dict, input_path: str | None, conf: Confinement, errors: list[RecipeError]
) -> list[SourceSpec]:
    specs: list[SourceSpec] = []
    for i, s in enumerate(top["sources"] or []):
        sp = check_section(s, SOURCE_FIELDS, file, lines, ("sources", i), errors)
        kind = sp["kind"]
        if kind is None:
            continue
        if kind not in source_names():
            errors.append(
                RecipeError(
                    file,
                    line_of(lines, ("sources", i, "kind")),
                    f"unknown source kind {kind!r} (known: {', '.join(source_names())})",
                )
            )
            continue
        inp = input_path
        if inp is None and sp["input"] is not None:
            resolved = conf.check(sp["input"], conf.recipe_dir, ("sources", i, "input"), f"sources.{i}.input")
            inp = None if resolved is None else str(resolved)
        if inp is not None:
            conf.allow(inp)
        cfg = _source_config(kind, sp["config"], file, lines, ("sources", i, "config"), errors, conf, inp)
        if inp is not None:
            cfg["_input"] = inp  # sources resolve their (relative) unit keys against it in load()
        specs.append(SourceSpec(i, kind, sp["weight"], sp["scenes"], inp, cfg))
    return specs


def _check_mix(top: dict, specs: list[SourceSpec], file: str, lines: dict, errors: list[RecipeError]) -> None:
    """Some source must receive units: weights of the split sources must not all be 0."""
    if top["sources"] is not None and not top["sources"]:
        errors.append(RecipeError(file, line_of(lines, ("sources",)), "sources must list at least one source"))
    weighted = [s for s in specs if s.scenes is None]
    if weighted and not any(s.weight > 0 for s in weighted):
        errors.append(
            RecipeError(
                file,
                line_of(lines, ("sources",)),
                "every source has weight 0 (give one a weight > 0 or a fixed `scenes:`)",
            )
        )


def _qa(top: dict, file: str, lines: dict, errors: list[RecipeError]) -> tuple[Any, list[Path]]:
    try:
        qa_cfg = load_qa_config(top["qa"] or {}, file, lines)
    except RecipeError as e:
        errors.append(e)
    except RecipeErrors as e:
        errors.extend(e.errors)
    else:
        return qa_cfg, [Path(p) for p in getattr(qa_cfg, "source_files", [])]
    return None, []


def load_recipe(
    path: str | Path,
    *,
    seed: int | None = None,
    scenes: int | None = None,
    input_path: str | None = None,
    allow_roots: tuple[str, ...] = (),
) -> Recipe:
    """Load, validate and compile a recipe. Raises RecipeErrors listing every problem found.

    Overrides (`seed`, `scenes`, `input_path`, as given on the command line) pass the same checks as the
    recipe's own values; every path the recipe names is confined (recipe_paths.py), `allow_roots` adding
    folders the user allowed explicitly."""
    check_overrides(seed, scenes)
    file = str(path)
    data, lines = load_yaml(path)
    if data is None:
        raise RecipeError(file, 1, "empty recipe")
    errors: list[RecipeError] = []
    top = check_section(data, TOP_FIELDS, file, lines, (), errors)
    nan_errors: list[RecipeError] = []
    non_finite(data, file, lines, nan_errors)
    errors += [e for e in nan_errors if str(e) not in {str(x) for x in errors}]  # free-form sections too
    conf = Confinement(file, lines, errors, allow_roots)
    specs = _sources(top, file, lines, input_path, conf, errors)
    _check_mix(top, specs, file, lines, errors)
    shards = check_section(top["shards"], SHARD_FIELDS, file, lines, ("shards",), errors)
    check_templates(top["qa"], conf)
    check_rewrite(top["rewrite"], conf)
    splits = check_splits(top["splits"], file, lines, errors)
    graph_cfg = dict(top["graph"] or {})
    check_graph_section(top["graph"], file, lines, errors)  # keys, thresholds, truth (graph/config.py)
    qa_cfg, deps = _qa(top, file, lines, errors) if not errors else (None, [])
    rewrite_cfg = None
    if top["rewrite"] is not None and not errors:
        try:
            rewrite_cfg = load_rewrite_config(top["rewrite"], file, lines)
        except RecipeError as e:
            errors.append(e)
        except RecipeErrors as e:
            errors.extend(e.errors)
        deps += [Path(p) for p in getattr(rewrite_cfg, "source_files", ())]
    if errors:
        raise RecipeErrors(errors)
    h = hashlib.sha256(Path(file).read_bytes())
    for d in sorted(set(deps)):
        h.update(d.name.encode() + b"\0" + d.read_bytes())
    return Recipe(
        path=file,
        name=top["name"] or Path(file).stem,
        seed=top["seed"] if seed is None else seed,
        scenes=top["scenes"] if scenes is None else scenes,
        sources=specs,
        graph=graph_cfg,
        qa=qa_cfg,
        shards=shards,
        hash=h.hexdigest(),
        raw=data,
        splits=splits,
        rewrite=rewrite_cfg,
    )


def recipe_fingerprint(recipe: Recipe) -> dict[str, Any]:
    """What identifies a run's output (stored in index.json): recipe hash, seed, scenes, code version."""
    from refspatial_gen import __version__

    return {
        "recipe": Path(recipe.path).name,
        "recipe_hash": recipe.hash,
        "seed": recipe.seed,
        "scenes": recipe.scenes,
        "code_version": __version__,
        "sources": [
            {"kind": s.kind, "weight": s.weight, "input": None if s.input is None else Path(s.input).name}
            for s in recipe.sources
        ],
    }


def fingerprint_bytes(recipe: Recipe) -> bytes:
    return dumps(recipe_fingerprint(recipe))
