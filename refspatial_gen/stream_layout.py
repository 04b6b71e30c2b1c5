"""Which items of an epoch each reader slot reads, in which order: pure arithmetic, no file access.

Why separate from the reader: a resume on a different number of ranks must know exactly which items
the old slots had handed out. Positions are global item numbers in the epoch's order (shards permuted
by (seed, epoch), items in file order); a slot's items and its shuffle-buffer order are functions of
(positions, seed, epoch, slot) only, so they can be replayed with integers instead of samples.

Ranges are sorted, disjoint, half-open `(start, stop)` pairs.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from itertools import islice
from typing import TypeVar

import numpy as np

T = TypeVar("T")
Ranges = list[tuple[int, int]]


def complement(n: int, done: Ranges) -> Ranges:
    """[0, n) minus `done`."""
    out, pos = [], 0
    for a, b in done:
        if a > pos:
            out.append((pos, min(a, n)))
        pos = max(pos, b)
    if pos < n:
        out.append((pos, n))
    return [(a, b) for a, b in out if a < b]


def count(ranges: Ranges) -> int:
    return sum(b - a for a, b in ranges)


def take(ranges: Ranges, lo: int, hi: int) -> Ranges:
    """The items with rank lo..hi-1 (0-based, in order) of the positions `ranges` cover, as ranges."""
    out, seen = [], 0
    for a, b in ranges:
        n = b - a
        s, e = max(lo - seen, 0), min(hi - seen, n)
        if s < e:
            out.append((a + s, a + e))
        seen += n
        if seen >= hi:
            break
    return out


def slot_ranges(n: int, done: Ranges, slot: int, slots: int) -> Ranges:
    """Slot `slot` of `slots` takes one contiguous share (sizes differ by at most one) of the items not
    in `done`; with nothing done that is the plain range [n*slot/slots, n*(slot+1)/slots)."""
    free = complement(n, done)
    m = count(free)
    return take(free, m * slot // slots, m * (slot + 1) // slots)


def to_ranges(positions: Iterable[int]) -> Ranges:
    """Sorted, merged ranges covering the given positions."""
    out: Ranges = []
    for p in sorted(set(int(x) for x in positions)):
        if out and out[-1][1] == p:
            out[-1] = (out[-1][0], p + 1)
        else:
            out.append((p, p + 1))
    return out


def union(a: Ranges, b: Ranges) -> Ranges:
    out: Ranges = []
    for s, e in sorted(list(a) + list(b)):
        if out and s <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], e))
        else:
            out.append((s, e))
    return out


def positions(ranges: Ranges) -> Iterator[int]:
    for a, b in ranges:
        yield from range(a, b)


def shuffle_buffer(items: Iterable[T], rng: np.random.Generator, size: int) -> Iterator[T]:
    """A bounded shuffle: fill a buffer of `size`, then emit a random element per new item, then drain.

    Depends only on the number of items and `rng`, so replaying it on positions gives the order the
    same call gave the items.
    """
    buf: list[T] = []
    for it in items:
        if len(buf) < size:
            buf.append(it)
            continue
        j = int(rng.integers(len(buf)))
        buf[j], it = it, buf[j]
        yield it
    while buf:
        j = int(rng.integers(len(buf)))
        buf[j], last = buf[-1], buf[j]
        buf.pop()
        yield last


def slot_rng(seed: int, epoch: int, slot: int, resplit: int) -> np.random.Generator:
    key = [seed, epoch, slot, 0xB0F] + ([resplit] if resplit else [])
    return np.random.default_rng(key)


def slot_order(
    n: int, done: Ranges, slot: int, slots: int, *, seed: int, epoch: int, resplit: int, shuffle: bool, buffer_size: int
) -> Iterator[int]:
    """The positions slot `slot` yields, in yield order (what the reader does, without reading)."""
    mine = positions(slot_ranges(n, done, slot, slots))
    if not shuffle or buffer_size <= 1:
        return mine
    return shuffle_buffer(mine, slot_rng(seed, epoch, slot, resplit), buffer_size)


def consumed(n: int, done: Ranges, slots: int, progress: dict[int, int], **order) -> Ranges:
    """`done` plus the first progress[s] positions each slot s yielded: what a checkpoint has used up."""
    used: list[int] = []
    for s, k in progress.items():
        if not 0 <= s < slots:
            raise ValueError(f"progress names slot {s}, but the state has {slots} slots")
        got = list(islice(slot_order(n, done, s, slots, **order), int(k)))
        if len(got) != int(k):
            raise ValueError(f"progress says slot {s} yielded {k} items, but it holds only {len(got)}")
        used += got
    return union(done, to_ranges(used))
