"""The recipe's `qa:` section: families of templates with weights, per-sample limits, balance, step mix.

Why compiled here: the run loads the recipe once and every worker reuses the compiled templates; any error
in the section or in a template file it names stops the run before work starts, as `file:line: message`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.qa.templates import Template, compile_templates
from refspatial_gen.schema import Field, check_section
from refspatial_gen.yamlpos import line_of, load_yaml

MAX_QA_PER_SAMPLE = 15


def _check_steps(v: Any) -> str | None:
    if not isinstance(v, dict):
        return "must map a step count (1-5) to a weight"
    for k, w in v.items():
        try:
            n = int(k)
        except (TypeError, ValueError):
            return f"step count {k!r} is not an integer"
        if not 1 <= n <= 5:
            return f"step count {n} out of range 1..5"
        if isinstance(w, bool) or not isinstance(w, (int, float)) or w < 0:
            return f"weight for {n} steps must be a number >= 0"
    return None


QA_FIELDS: dict[str, Field] = {
    "families": Field(dict, required=True, doc="family name -> {weight, templates: [files relative to the recipe]}"),
    "max_per_sample": Field(
        int,
        default=MAX_QA_PER_SAMPLE,
        min=1,
        max=MAX_QA_PER_SAMPLE,
        doc="QA pairs per sample (a conversation), at most 15",
    ),
    "attempts": Field(int, default=60, min=1, max=10000, doc="template attempts per sample before giving up"),
    "budget": Field(int, default=400, min=10, max=1000000, doc="step executions per template attempt (search budget)"),
    "steps": Field(
        dict,
        default=None,
        check=_check_steps,
        doc="step-count mix: a template's weight is multiplied by the weight of its step count",
    ),
    "point_slack": Field(
        int,
        default=1,
        min=0,
        max=100,
        doc="balance: an answer point may make its image quadrant lead the rarest one by at most this",
    ),
    "multiview_pairs": Field(int, default=2, min=0, max=15, doc="multi-view questions per multi-frame sample"),
    "point_depth": Field(
        int,
        default=0,
        min=0,
        max=MAX_QA_PER_SAMPLE,
        doc="built-in point/depth questions (qa/pointdepth.py) added per sample; 0 = off",
    ),
}
FAMILY_FIELDS: dict[str, Field] = {
    "weight": Field(float, default=1.0, min=0.0),
    "templates": Field(list, required=True, doc="template files, relative to the recipe file"),
    "max_per_sample": Field(int, default=None, min=1, max=MAX_QA_PER_SAMPLE),
}


@dataclass
class Family:
    name: str
    weight: float
    templates: list[Template]
    max_per_sample: int | None = None


@dataclass
class QAConfig:
    families: list[Family]
    max_per_sample: int = MAX_QA_PER_SAMPLE
    attempts: int = 60
    budget: int = 400
    step_mix: dict[int, float] = field(default_factory=dict)
    point_slack: int = 1
    multiview_pairs: int = 2
    source_files: list[str] = field(default_factory=list)
    point_depth: int = 0  # built-in point/depth questions per sample (qa/pointdepth.py)

    @property
    def templates(self) -> list[Template]:
        return [t for f in self.families for t in f.templates]


def load_qa_config(
    section: dict[str, Any] | None, recipe_file: str, lines: dict[tuple[Any, ...], int], path: tuple[Any, ...] = ("qa",)
) -> QAConfig:
    """Validate the `qa:` section and compile every template file it names (once). Raises RecipeErrors."""
    errors: list[RecipeError] = []
    file = str(recipe_file)
    sec = check_section(section, QA_FIELDS, file, lines, path, errors)
    fams: list[Family] = []
    files: list[str] = []
    compiled: dict[str, list[Template]] = {}
    for name, spec in (sec["families"] or {}).items():
        fp = path + ("families", name)
        if not isinstance(name, str) or not name.replace("_", "").isalnum():
            errors.append(RecipeError(file, line_of(lines, fp), f"family name {name!r} must be a word"))
            continue
        fs = check_section(spec, FAMILY_FIELDS, file, lines, fp, errors)
        temps: list[Template] = []
        for j, rel in enumerate(fs["templates"] or []):
            tp = fp + ("templates", j)
            if not isinstance(rel, str) or not rel:
                errors.append(RecipeError(file, line_of(lines, tp), f"template path must be a string, got {rel!r}"))
                continue
            tfile = Path(file).parent / rel
            if not tfile.is_file():
                errors.append(RecipeError(file, line_of(lines, tp), f"template file not found: {rel}"))
                continue
            key = str(tfile.resolve())
            if key not in compiled:
                try:
                    data, tlines = load_yaml(tfile)
                except RecipeError as e:
                    errors.append(e)
                    continue
                compiled[key] = compile_templates(data, str(tfile), tlines, errors)
                files.append(key)
            for t in compiled[key]:
                t2 = _copy_for_family(t, name)
                temps.append(t2)
        if not temps and not errors:
            errors.append(RecipeError(file, line_of(lines, fp), f"family {name!r} has no templates"))
        fams.append(Family(name, fs["weight"], temps, fs["max_per_sample"]))
    if sec["families"] is not None and not sec["families"]:
        errors.append(RecipeError(file, line_of(lines, path + ("families",)), "families must name at least one family"))
    if errors:
        raise RecipeErrors(errors)
    if not any(f.weight > 0 and f.templates for f in fams):
        raise RecipeError(file, line_of(lines, path + ("families",)), "every family has weight 0")
    mix = {int(k): float(v) for k, v in (sec["steps"] or {}).items()}
    return QAConfig(
        fams,
        sec["max_per_sample"],
        sec["attempts"],
        sec["budget"],
        mix,
        sec["point_slack"],
        sec["multiview_pairs"],
        sorted(files),
        sec["point_depth"],
    )


def _copy_for_family(t: Template, family: str) -> Template:
    from dataclasses import replace

    return replace(t, family=family)
