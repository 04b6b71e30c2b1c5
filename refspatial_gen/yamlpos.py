"""YAML loading that remembers the line of every key and item, so errors read `file:line: message`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from refspatial_gen.core.errors import RecipeError

Path_ = tuple  # a key path into the document, e.g. ("sources", 0, "kind")


def _construct(node: yaml.Node, path: tuple, lines: dict[tuple, int], file: str) -> Any:
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: dict[Any, Any] = {}
        for k_node, v_node in node.value:
            if not isinstance(k_node, yaml.ScalarNode):
                raise RecipeError(file, k_node.start_mark.line + 1, "mapping keys must be plain scalars")
            key = k_node.value
            if key in out:
                raise RecipeError(file, k_node.start_mark.line + 1, f"duplicate key {key!r}")
            out[key] = _construct(v_node, path + (key,), lines, file)
            lines[path + (key,)] = k_node.start_mark.line + 1
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_construct(v, path + (i,), lines, file) for i, v in enumerate(node.value)]
    loader = yaml.SafeLoader("")
    return loader.construct_object(node, deep=True)


def load_yaml(path: str | Path, text: str | None = None) -> tuple[Any, dict[tuple, int]]:
    """Parse YAML -> (plain Python data, {key path: 1-based line}). Syntax errors become RecipeError."""
    file = str(path)
    if text is None:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as e:
            raise RecipeError(file, None, f"cannot read: {e.strerror or e}") from e
        except UnicodeDecodeError as e:
            raise RecipeError(file, None, f"not UTF-8 text: {e}") from e
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        raise RecipeError(file, mark.line + 1 if mark else None, f"YAML syntax: {e.problem or e}") from e
    except yaml.YAMLError as e:
        raise RecipeError(file, None, f"YAML: {e}") from e
    lines: dict[tuple, int] = {}
    if node is None:
        return None, {(): 1}
    try:
        return _construct(node, (), lines, file), lines
    except yaml.constructor.ConstructorError as e:
        mark = e.problem_mark
        raise RecipeError(file, mark.line + 1 if mark else None, f"YAML: {e.problem}") from e


def line_of(lines: dict[tuple, int], path: tuple) -> int | None:
    """Line of `path`, or of its closest ancestor that has one."""
    p = tuple(path)
    while p not in lines and p:
        p = p[:-1]
    return lines.get(p)
