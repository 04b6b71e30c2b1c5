"""Where asset files live: paths in a catalog resolve relative to the file that names them.

Prefixes: `shared:<p>` resolves under $REFSPATIAL_SHARED_DATA (default ../shared/data next to the
repository), `cache:<p>` under the asset cache ($REFSPATIAL_CACHE, default ~/.cache/refspatial-gen),
`$VAR/...` is expanded, an absolute path is kept, anything else is relative to the naming file's folder.
Why prefixes: a catalog made by `assets import` on the shared data or with cached convex decompositions
stays valid when those folders move; only the environment variable changes.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def shared_data_root() -> Path:
    """$REFSPATIAL_SHARED_DATA, else ../shared/data next to the repository."""
    env = os.environ.get("REFSPATIAL_SHARED_DATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "data"


def cache_root() -> Path:
    """The asset cache (convex decompositions, downloaded asset packages): never inside the package."""
    env = os.environ.get("REFSPATIAL_CACHE")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "refspatial-gen"


def resolve_path(spec: str, base: Path | None = None) -> Path:
    """A catalog path spec -> an absolute path (see the module docstring)."""
    if spec.startswith("shared:"):
        return shared_data_root() / spec[len("shared:") :]
    if spec.startswith("cache:"):
        return cache_root() / spec[len("cache:") :]
    p = Path(os.path.expandvars(spec)).expanduser()
    if p.is_absolute():
        return p
    return ((base if base is not None else Path.cwd()) / p).resolve()


def missing_hint(spec: str) -> str:
    """What to tell a user whose path does not exist."""
    if spec.startswith("shared:"):
        env = os.environ.get("REFSPATIAL_SHARED_DATA")
        where = f"$REFSPATIAL_SHARED_DATA={env}" if env else f"the default shared data folder {shared_data_root()}"
        return (
            f" (resolved under {where}; set REFSPATIAL_SHARED_DATA to the folder that holds {spec[7:].split('/')[0]}/)"
        )
    if spec.startswith("cache:"):
        return (
            f" (resolved under the asset cache {cache_root()}; set REFSPATIAL_CACHE, or run "
            "`refspatial-gen assets import` again to rebuild it)"
        )
    return ""


def portable_spec(path: Path, base: Path) -> str:
    """The spec to write into a catalog at `base` for `path`: shared:/cache: when under those roots,
    else relative to `base` when possible, else absolute."""
    path = path.resolve()
    for prefix, root in (("shared:", shared_data_root()), ("cache:", cache_root())):
        try:
            return prefix + path.relative_to(root.resolve()).as_posix()
        except ValueError:
            pass
    try:
        return Path(os.path.relpath(path, base.resolve())).as_posix()
    except ValueError:  # another drive
        return path.as_posix()
