"""`refspatial-gen recipes lint PATH...`: every problem in recipes and template files as file:line: message.

A file with a top-level `templates:` list is a template file; anything else is a recipe (checked by the
recipe loader, which compiles the templates its `qa:` section names).
"""

from __future__ import annotations

from pathlib import Path

from refspatial_gen.core.errors import RecipeError, RecipeErrors
from refspatial_gen.qa.templates import compile_templates
from refspatial_gen.yamlpos import load_yaml


def lint_file(path: str | Path) -> list[RecipeError]:
    """All problems of one file ([] when clean). Never raises for bad content."""
    file = str(path)
    try:
        data, lines = load_yaml(path)
    except RecipeError as e:
        return [e]
    if isinstance(data, dict) and "templates" in data and "sources" not in data:
        errors: list[RecipeError] = []
        compile_templates(data, file, lines, errors)
        return errors
    from refspatial_gen.recipe import load_recipe

    try:
        load_recipe(path)
    except RecipeErrors as e:
        return list(e.errors)
    except RecipeError as e:
        return [e]
    return []


def lint_paths(paths: list[str]) -> list[RecipeError]:
    out: list[RecipeError] = []
    for p in paths:
        out += lint_file(p)
    return out
