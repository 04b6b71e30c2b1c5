"""Path confinement for recipes: every file or folder a recipe names must lie under an allowed root.

Why: a recipe is data that may come from someone else. It must not make the tool read (and quote in an
error) `/etc/shadow`, or write outside the output root. Allowed roots for what a recipe reads:

  * the recipe's own folder,
  * the input folder (`--input`, or the recipe's `input:`, itself confined),
  * the project's shipped `recipes/` and `assets/` folders, and `out/assets/` (imported catalogs),
  * folders the user allows explicitly: `--allow-root DIR` or REFSPATIAL_ALLOWED_ROOTS (os.pathsep list).

Paths are resolved the way the code that opens them resolves them (templates, `input:` and the sim
`catalog` against the recipe's folder, image `annotations`/`images_dir` against the input folder, model
paths against the working directory), symlinks followed, then checked. A path outside is a RecipeError that
quotes the key and the value written in the recipe, never the file's contents (the file is not opened).
The dataset `name` becomes a folder under the output root, so it must be a plain folder name.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from refspatial_gen.core.errors import RecipeError
from refspatial_gen.yamlpos import line_of

ALLOWED_ROOTS_ENV = "REFSPATIAL_ALLOWED_ROOTS"
PROJECT = Path(__file__).resolve().parents[1]
# the project's shipped recipes and assets, and the catalogs `refspatial-gen assets import` writes (make assets-*)
SHIPPED_ROOTS = (PROJECT / "recipes", PROJECT / "assets", PROJECT / "out" / "assets")
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")

# (source kind, key path inside its config) -> what a relative value is resolved against
CONFIG_PATHS: dict[tuple[str, tuple[str, ...]], str] = {
    ("image", ("annotations",)): "input",
    ("image", ("images_dir",)): "input",
    ("image", ("depth", "model_dir")): "cwd",
    ("image", ("depth", "model_path")): "cwd",
    ("scan", ("input",)): "cwd",
    ("scan", ("boxes_file",)): "cwd",
    ("sim", ("catalog",)): "recipe",  # a path or a list of paths; "builtin" is the shipped catalog
}
_BUILTIN = ("builtin", "")
_PATHLIKE_SUFFIXES = ("_file", "_dir", "_path", "_folder")


def check_name(name: Any) -> str | None:
    """The dataset name is a folder under out/shards: letters, digits, '.', '_', '-' only, no leading dot."""
    if isinstance(name, str) and NAME_RE.match(name) and name not in (".", ".."):
        return None
    return "must be a plain folder name (letters, digits, '.', '_', '-'; at most 100; not starting with '.')"


def explicit_roots(extra: Iterable[str] = ()) -> list[Path]:
    env = [p for p in os.environ.get(ALLOWED_ROOTS_ENV, "").split(os.pathsep) if p.strip()]
    return [Path(p).expanduser().resolve() for p in [*env, *extra]]


def is_under(path: Path, root: Path) -> bool:
    return path == root or root in path.parents


class Confinement:
    """The allowed roots of one recipe load, and the check that records an error for a path outside them."""

    def __init__(self, recipe_file: str, lines: dict, errors: list[RecipeError], extra: Iterable[str] = ()) -> None:
        self.file, self.lines, self.errors = recipe_file, lines, errors
        self.recipe_dir = Path(
            recipe_file
        ).parent.resolve()  # as the loaders join it (a symlinked recipe keeps its folder)
        self.roots = [self.recipe_dir, *SHIPPED_ROOTS, *explicit_roots(extra)]

    def allow(self, root: str | Path) -> None:
        self.roots.append(Path(root).resolve())

    def check(self, value: Any, base: Path, where: tuple, key_name: str) -> Path | None:
        """The resolved path when `value` lies under an allowed root; else record a RecipeError, return None."""
        if not isinstance(value, str) or not value:
            return None  # type errors are the schema's job
        if "\0" in value:
            self._err(where, f"{key_name}: path contains a NUL byte")
            return None
        p = Path(value).expanduser()
        try:
            resolved = (p if p.is_absolute() else base / p).resolve()
        except (OSError, RuntimeError, ValueError):  # symlink loop, unreadable component
            self._err(where, f"{key_name}: path {value!r} cannot be resolved")
            return None
        if any(is_under(resolved, r) for r in self.roots):
            return resolved
        self._err(
            where,
            f"{key_name}: path {value!r} is outside the allowed folders (the recipe's folder, "
            f"the input folder, the shipped recipes/ and assets/, --allow-root or "
            f"{ALLOWED_ROOTS_ENV})",
        )
        return None

    def _err(self, where: tuple, msg: str) -> None:
        self.errors.append(RecipeError(self.file, line_of(self.lines, where), msg))


def _dotted(path: tuple) -> str:
    return ".".join(str(p) for p in path)


def check_templates(qa: Any, conf: Confinement) -> None:
    """qa.families.*.templates[*] are resolved against the recipe's folder and confined."""
    if not isinstance(qa, dict) or not isinstance(qa.get("families"), dict):
        return
    for fam, spec in qa["families"].items():
        if not isinstance(spec, dict) or not isinstance(spec.get("templates"), list):
            continue
        for j, rel in enumerate(spec["templates"]):
            where = ("qa", "families", fam, "templates", j)
            conf.check(rel, conf.recipe_dir, where, _dotted(where))


def _get(d: Any, keys: tuple[str, ...]) -> Any:
    for k in keys:
        if not isinstance(d, dict):
            return None
        d = d.get(k)
    return d


def _pathlike_keys(d: Any, prefix: tuple = ()) -> list[tuple[str, ...]]:
    out: list[tuple[str, ...]] = []
    if isinstance(d, dict):
        for k, v in d.items():
            if isinstance(v, dict):
                out += _pathlike_keys(v, prefix + (k,))
            elif isinstance(k, str) and k.endswith(_PATHLIKE_SUFFIXES) and isinstance(v, str):
                out.append(prefix + (k,))
    return out


def check_source_config(kind: str, config: Any, index: int, input_root: str | None, conf: Confinement) -> None:
    """Path-valued keys of one source's config (the table above, plus any key named *_file/_dir/_path)."""
    keys = {k: base for (kd, k), base in CONFIG_PATHS.items() if kd == kind}
    for k in _pathlike_keys(config):
        keys.setdefault(k, "cwd")
    for key, base in sorted(keys.items()):
        value = _get(config, key)
        if value is None:
            continue
        if base == "input":
            if not input_root:
                continue  # no input folder: planning stops with its own error
            root = Path(input_root)
        else:
            root = conf.recipe_dir if base == "recipe" else Path.cwd()
        where = ("sources", index, "config", *key)
        values = value if isinstance(value, list) else [value]
        for j, v in enumerate(values):
            if v in _BUILTIN:
                continue
            w = where + (j,) if isinstance(value, list) else where
            conf.check(v, root, w, _dotted(w))


REWRITE_PATHS = ("prompts", "cache")  # the rewrite stage's prompt file (read) and reply cache (written)


def check_rewrite(section: Any, conf: Confinement) -> None:
    """`rewrite.prompts` / `rewrite.cache` are resolved against the recipe's folder and confined."""
    if not isinstance(section, dict):
        return
    for key in REWRITE_PATHS:
        if section.get(key) is not None:
            conf.check(section[key], conf.recipe_dir, ("rewrite", key), f"rewrite.{key}")
