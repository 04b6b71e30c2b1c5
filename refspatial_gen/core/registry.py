"""One plug-in registry: name -> an object, or a lazily imported "module:attribute".

Why one class: sources, scan readers, depth estimators, step ops, relations (and exporters) are all chosen
by name from a recipe or a template; each kind keeps its own Registry instance, so listing the names and the
error for an unknown name read the same everywhere, and heavy modules load only when their entry is used.

    SOURCES = Registry("source")
    SOURCES.add("sim", "refspatial_gen.sources.sim:SimSource")   # imported on first get()
    SOURCES.get("sim")  -> the class;  SOURCES.names() -> ["sim", ...];  SOURCES.get("x") -> UnknownName
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from typing import Generic, TypeVar

T = TypeVar("T")


class UnknownName(KeyError):
    """A name no entry of the registry has; the message lists the known names."""

    def __init__(self, kind: str, name: object, known: list[str]) -> None:
        self.message = f"unknown {kind} {name!r} (known: {', '.join(known) or 'none'})"
        super().__init__(self.message)

    def __str__(self) -> str:
        return self.message


class Registry(Generic[T]):
    """Entries in registration order (an order some kinds use: scan-reader detection, stored relations)."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._targets: dict[str, str | T] = {}
        self._loaded: dict[str, T] = {}

    def add(self, name: str, target: str | T, *, replace: bool = False) -> None:
        """Register `target` (an object, or "module:attribute" imported on first use) under `name`."""
        if name in self._targets and not replace:
            raise ValueError(f"{self.kind} {name!r} registered twice")
        self._targets[name] = target
        self._loaded.pop(name, None)
        if not isinstance(target, str):
            self._loaded[name] = target

    def remove(self, name: str) -> None:
        """Forget an entry (tests that register a toy plug-in clean up after themselves)."""
        self._targets.pop(name, None)
        self._loaded.pop(name, None)

    def get(self, name: str) -> T:
        hit = self._loaded.get(name)
        if hit is not None:
            return hit
        if name not in self._targets:
            raise UnknownName(self.kind, name, sorted(self._targets))
        target = self._targets[name]
        if isinstance(target, str):
            mod, _, attr = target.partition(":")
            value: T = getattr(importlib.import_module(mod), attr)
        else:
            value = target
        self._loaded[name] = value
        return value

    def __getitem__(self, name: str) -> T:
        hit = self._loaded.get(name)  # the hot path (relation lookups): one dict read
        return hit if hit is not None else self.get(name)

    @property
    def loaded(self) -> dict[str, T]:
        """The entries imported so far (every object entry), as a live dict: a plain lookup for hot paths that
        know their entries are objects (relations). Read it, never write it."""
        return self._loaded

    def values(self) -> list[T]:
        """Every entry (imported), in registration order."""
        return [self.get(n) for n in self._targets]

    def names(self) -> list[str]:
        """Registered names, in registration order."""
        return list(self._targets)

    def __contains__(self, name: object) -> bool:
        return name in self._targets

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._targets))

    def __len__(self) -> int:
        return len(self._targets)
