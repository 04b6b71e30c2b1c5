"""YAML loading that remembers the line of every key and item, so errors read `file:line: message`.

Safe by construction: only plain data (PyYAML's SafeLoader rules for scalars; mappings and sequences built
here, so a `!!python/...` tag never executes), and bounded, so a hostile recipe cannot exhaust the
machine: the file size (`MAX_BYTES`), the nesting depth (`MAX_DEPTH`, checked while composing, before
Python's recursion limit is near) and the number of nodes after alias expansion (`MAX_NODES`: a
"billion laughs" document stops at once) are limited. Every failure is a RecipeError.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

import yaml

from refspatial_gen.core.errors import RecipeError

Path_ = tuple  # a key path into the document, e.g. ("sources", 0, "kind")

MAX_BYTES = 4 * 1024 * 1024  # recipes, templates and catalogs are a few kB; 4 MiB is far beyond any real one
MAX_DEPTH = 64  # nesting levels (real files use < 10)
MAX_NODES = 250_000  # nodes built, aliases expanded (the shipped catalog has ~3,000)
_PLAIN_TAGS = (yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG)


class _Limit(Exception):
    def __init__(self, line: int | None, message: str) -> None:
        super().__init__(message)
        self.line, self.message = line, message


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader whose composer refuses documents nested deeper than MAX_DEPTH."""

    _depth = 0

    def compose_node(self, parent, index):  # type: ignore[override]
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                ev = self.peek_event()
                raise _Limit(ev.start_mark.line + 1, f"nested deeper than {MAX_DEPTH} levels")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


class _Builder:
    """Turns composed nodes into plain data and records lines; counts nodes so aliases cannot explode."""

    def __init__(self, file: str) -> None:
        self.file, self.lines, self.nodes = file, {}, 0
        self._scalars = yaml.SafeLoader("")

    def build(self, node: yaml.Node, path: tuple) -> Any:
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise _Limit(
                node.start_mark.line + 1, f"more than {MAX_NODES} values after expanding aliases (an alias bomb?)"
            )
        line = node.start_mark.line + 1
        self.lines[path] = line
        if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)) and node.tag not in _PLAIN_TAGS:
            raise RecipeError(self.file, line, f"unsupported YAML tag {node.tag!r} (plain data only)")
        if isinstance(node, yaml.MappingNode):
            out: dict[Any, Any] = {}
            for k_node, v_node in node.value:
                if not isinstance(k_node, yaml.ScalarNode):
                    raise RecipeError(self.file, k_node.start_mark.line + 1, "mapping keys must be plain scalars")
                key = k_node.value
                if key in out:
                    raise RecipeError(self.file, k_node.start_mark.line + 1, f"duplicate key {key!r}")
                out[key] = self.build(v_node, path + (key,))
                self.lines[path + (key,)] = k_node.start_mark.line + 1
            return out
        if isinstance(node, yaml.SequenceNode):
            return [self.build(v, path + (i,)) for i, v in enumerate(node.value)]
        try:
            return self._scalars.construct_object(node, deep=True)
        except yaml.YAMLError as e:
            raise RecipeError(self.file, line, f"YAML: {getattr(e, 'problem', None) or 'bad value'}") from e
        except (ValueError, TypeError, AttributeError, OverflowError) as e:
            raise RecipeError(self.file, line, f"YAML: value with tag {node.tag!r} cannot be read") from e


def _read_text(path: str | Path) -> str:
    file = str(path)
    try:
        st = os.stat(file)
    except OSError as e:
        raise RecipeError(file, None, f"cannot read: {e.strerror or e}") from e
    if not stat.S_ISREG(st.st_mode):
        raise RecipeError(file, None, "not a regular file")
    if st.st_size > MAX_BYTES:
        raise RecipeError(file, None, f"file is {st.st_size} bytes; the limit is {MAX_BYTES}")
    try:
        with open(file, "rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as e:
        raise RecipeError(file, None, f"cannot read: {e.strerror or e}") from e
    if len(raw) > MAX_BYTES:
        raise RecipeError(file, None, f"file is larger than the limit of {MAX_BYTES} bytes")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise RecipeError(file, None, f"not UTF-8 text (byte {e.start})") from e


def load_yaml(path: str | Path, text: str | None = None) -> tuple[Any, dict[tuple, int]]:
    """Parse YAML -> (plain Python data, {key path: 1-based line}). Every problem becomes a RecipeError."""
    file = str(path)
    if text is None:
        text = _read_text(path)
    elif len(text) > MAX_BYTES:
        raise RecipeError(file, None, f"text is larger than the limit of {MAX_BYTES} bytes")
    try:
        node = yaml.compose(text, Loader=_BoundedLoader)
    except _Limit as e:
        raise RecipeError(file, e.line, f"YAML: {e.message}") from None
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        raise RecipeError(file, mark.line + 1 if mark else None, f"YAML syntax: {e.problem or e.context}") from None
    except yaml.YAMLError as e:  # ReaderError: a control character; its message names only the character
        first = (str(e).splitlines() or [type(e).__name__])[0]
        raise RecipeError(file, None, f"YAML: {first[:120]}") from None
    except RecursionError:
        raise RecipeError(file, None, "YAML: nested too deeply") from None
    if node is None:
        return None, {(): 1}
    builder = _Builder(file)
    try:
        return builder.build(node, ()), builder.lines
    except _Limit as e:
        raise RecipeError(file, e.line, f"YAML: {e.message}") from None
    except RecursionError:
        raise RecipeError(file, None, "YAML: nested too deeply") from None


def line_of(lines: dict[tuple, int], path: tuple) -> int | None:
    """Line of `path`, or of its closest ancestor that has one."""
    p = tuple(path)
    while p not in lines and p:
        p = p[:-1]
    return lines.get(p)
