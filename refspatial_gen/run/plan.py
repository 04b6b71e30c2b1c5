"""Planning: recipe -> ordered work units -> shard groups. Decided once, before any work, by a fixed rule.

A unit's shard depends only on its position in the plan, never on completion order, so every executor
(1 worker, N workers, Ray) writes the same bytes.
"""

from __future__ import annotations

import hashlib
import os
import struct
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from refspatial_gen.core.errors import DropUnit, InputError
from refspatial_gen.recipe import Recipe, SourceSpec
from refspatial_gen.sources import get_source

FOLDER_ONLY = ("image",)  # sources whose input must be a folder (scan also reads single .mcap/.usd files)


@dataclass(frozen=True)
class Unit:
    uid: str  # globally unique in the run: "s<source index>/<source unit key>"
    source_index: int
    kind: str
    key: str  # the source's own unit key


@dataclass(frozen=True)
class Group:
    index: int
    units: tuple[Unit, ...]

    @property
    def name(self) -> str:
        return f"shard-{self.index:05d}"


def split_by_weight(total: int, weights: list[float]) -> list[int]:
    """Largest-remainder split of `total` units by weight (deterministic, sums exactly to total)."""
    w = np.asarray(weights, dtype=float)
    if w.sum() <= 0:
        raise ValueError("source weights sum to zero")
    exact = total * w / w.sum()
    base = np.floor(exact).astype(int)
    order = np.argsort(-(exact - base), kind="stable")
    base[order[: total - base.sum()]] += 1
    return base.tolist()


def check_input_root(path: str, kind: str) -> None:
    """The input root exists, is readable, is a folder where the source needs one, and is not empty."""
    p = Path(path)
    if not p.exists():
        raise InputError(path, "input does not exist" + (" (a broken symlink)" if p.is_symlink() else ""))
    if not os.access(p, os.R_OK):
        raise InputError(path, "input is not readable")
    if p.is_dir():
        try:
            empty = next(os.scandir(p), None) is None
        except OSError as e:
            raise InputError(path, f"input folder cannot be listed: {e.strerror or e}") from None
        if empty:
            raise InputError(path, "input folder is empty")
    elif kind in FOLDER_ONLY:
        raise InputError(path, f"input must be a folder (the {kind} source reads a folder of annotations and images)")


def _extensions_hint(path: str | None) -> str:
    """What the input holds, by file extension (tells a user why nothing was recognised)."""
    if not path or not Path(path).is_dir():
        return ""
    c: Counter = Counter()
    for i, (_, _, files) in enumerate(os.walk(path)):
        c.update(Path(f).suffix.lower() or "(none)" for f in files)
        if i > 200:
            break
    return "; it holds " + ", ".join(f"{n} {ext}" for ext, n in c.most_common(6)) if c else ""


def source_keys(s: SourceSpec, n: int) -> list[str]:
    """The source's unit keys; any failure to list them is an InputError naming the input (exit 2)."""
    where = s.input or f"sources[{s.index}] ({s.kind})"
    if s.input is not None:
        check_input_root(s.input, s.kind)
    try:
        keys = get_source(s.kind).unit_keys(s.config, n, s.input)
    except InputError:
        raise
    except DropUnit as e:
        raise InputError(where, f"{e.reason}: {e.detail}" if e.detail else e.reason) from None
    except (
        ValueError,
        OSError,
        KeyError,
        TypeError,
        IndexError,
        AttributeError,
        RuntimeError,
        EOFError,
        struct.error,
    ) as e:  # RuntimeError: what native parsers (pycolmap, USD) raise on a broken file
        msg = f"{e.strerror}: {e.filename}" if isinstance(e, OSError) and e.strerror else f"{e}"
        raise InputError(where, f"cannot list {s.kind} units: {msg or type(e).__name__}") from None
    if not keys:
        raise InputError(
            where, f"no {s.kind} units found: nothing the {s.kind} source can read{_extensions_hint(s.input)}"
        )
    return keys


def plan_units(recipe: Recipe) -> list[Unit]:
    weighted = [s for s in recipe.sources if s.scenes is None]
    fixed_total = sum(s.scenes for s in recipe.sources if s.scenes is not None)
    counts = dict(
        zip(
            [s.index for s in weighted],
            split_by_weight(max(recipe.scenes - fixed_total, 0), [s.weight for s in weighted]) if weighted else [],
        )
    )
    units: list[Unit] = []
    for s in recipe.sources:
        n = s.scenes if s.scenes is not None else counts[s.index]
        if n == 0:
            continue
        keys = source_keys(s, n)
        units.extend(Unit(f"s{s.index}/{k}", s.index, s.kind, k) for k in keys[:n])
    uids = [u.uid for u in units]
    if len(set(uids)) != len(uids):
        dup = next(u for u, c in Counter(uids).items() if c > 1)
        raise InputError(
            dup.split("/", 1)[0], f"the source produced the unit {dup!r} twice (duplicate ids in the input?)"
        )
    return units


def plan_groups(units: list[Unit], samples_per_shard: int) -> list[Group]:
    return [
        Group(i // samples_per_shard, tuple(units[i : i + samples_per_shard]))
        for i in range(0, len(units), samples_per_shard)
    ]


def unit_rng(seed: int, uid: str) -> np.random.Generator:
    """The unit's own generator, from (run seed, unit id) only."""
    digest = hashlib.sha256(uid.encode("utf-8")).digest()
    words = np.frombuffer(digest[:16], dtype="<u4").tolist()
    return np.random.default_rng(np.random.SeedSequence([seed, *words]))
