"""Streaming shards into training jobs: exactly once per epoch across ranks and workers, resumable.

Why this design:
- The epoch's global order is fixed by (seed, epoch): shards are permuted, items (samples, or QA pairs
  in QA mode) follow in file order. Each reader slot (rank x dataloader worker) takes one contiguous
  range of that order, sized to +-1 item, so every item is read exactly once, ranks get equal counts
  (DDP does not hang on uneven ranks), and a slot opens only the shards its range touches.
- A bounded shuffle buffer, seeded by (seed, epoch, slot), mixes items within a slot.
- Resume: the position in a slot is the number of items it has yielded; the stream is deterministic,
  so `load_state_dict` replays the slot's range up to that count without decoding any pixels and goes
  on from there: no repeats, no gaps.
- Images are decoded lazily: items keep the encoded message bytes until `.rgb()` / `.depth()` is called.

torch is optional: `ShardStream` is a plain iterable; `ShardStream.torch(...)` (or `TorchShardStream`)
gives a `torch.utils.data.IterableDataset` with the same behaviour.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.index import read_index
from refspatial_gen.shards.reader import ShardError, iter_raw

STATE_VERSION = 1


@dataclass
class StreamSample:
    """One sample from the stream; pixels are decoded on first use."""

    raw: RawSample
    shard: str
    slot: int = 0
    index: int = 0  # position within the slot's output this epoch
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def position(self) -> tuple[int, int]:
        return self.slot, self.index

    @property
    def header(self) -> dict:
        if "header" not in self._cache:
            self._cache["header"] = self.raw.header
        return self._cache["header"]

    @property
    def sample_id(self) -> str:
        return self.header["sample_id"]

    @property
    def qa(self) -> list[dict]:
        if "qa" not in self._cache:
            self._cache["qa"] = self.raw.qa_json()
        return self._cache["qa"]

    def frame_meta(self, view: int = 0) -> dict:
        return self.raw.frame_meta(view)

    def image_bytes(self, view: int = 0) -> tuple[bytes, str]:
        return self.raw.image_bytes(view)

    def rgb(self, view: int = 0) -> np.ndarray:
        return self.raw.rgb(view)

    def depth(self, view: int = 0) -> np.ndarray:
        return self.raw.depth(view)

    def decode(self):
        """The full core.model.Sample."""
        return self.raw.decode()


@dataclass
class StreamQA(StreamSample):
    """One QA pair with lazy access to the images of the sample it belongs to."""

    qa_index: int = 0

    @property
    def pair(self) -> dict:
        return self.qa[self.qa_index]

    @property
    def qa_id(self) -> str:
        return self.pair["qa_id"]


def _resolve_shards(source: str | Path | Sequence[str | Path]) -> list[tuple[Path, int, int]]:
    """[(path, samples, qa_pairs)] in index order (a directory with index.json) or as given (file list)."""
    if isinstance(source, (str, Path)) and Path(source).is_dir():
        d = Path(source)
        index = read_index(d)
        return [(d / s["name"], int(s["samples"]), int(s["qa_pairs"])) for s in index["shards"]]
    paths = [Path(source)] if isinstance(source, (str, Path)) else [Path(p) for p in source]
    out = []
    for p in paths:
        n = q = 0
        for raw in iter_raw(p, keep_topic=lambda t: False):
            n += 1
            q += int(raw.header["qa_pairs"])
        out.append((p, n, q))
    return out


def _default_topology() -> tuple[int, int, int, int]:
    """(rank, world_size, worker, num_workers) from torch.distributed / the dataloader worker, else env."""
    rank, world = int(os.environ.get("RANK", 0)), int(os.environ.get("WORLD_SIZE", 1))
    worker, workers = 0, 1
    torch = sys.modules.get("torch")
    if torch is not None:
        dist = torch.distributed
        if dist.is_available() and dist.is_initialized():
            rank, world = dist.get_rank(), dist.get_world_size()
        info = torch.utils.data.get_worker_info()
        if info is not None:
            worker, workers = info.id, info.num_workers
    return rank, world, worker, workers


class ShardStream:
    """Iterate samples (`mode="samples"`) or QA pairs (`mode="qa"`) of a shard directory or file list.

    rank/world_size/worker/num_workers default to torch.distributed, the dataloader worker info, or
    the RANK / WORLD_SIZE environment variables. `transform(item)` runs in the reader (dataloader worker),
    the place to decode pixels.
    """

    def __init__(self, source: str | Path | Sequence[str | Path], *, mode: str = "samples", shuffle: bool = True,
                 seed: int = 0, epoch: int = 0, buffer_size: int = 256, rank: int | None = None,
                 world_size: int | None = None, worker: int | None = None, num_workers: int | None = None,
                 transform: Callable[[StreamSample], Any] | None = None) -> None:
        if mode not in ("samples", "qa"):
            raise ValueError(f"mode must be 'samples' or 'qa', got {mode!r}")
        self.source = source
        self.shards = _resolve_shards(source)
        self.mode, self.shuffle, self.seed, self.epoch = mode, shuffle, int(seed), int(epoch)
        self.buffer_size = max(1, int(buffer_size))
        self._topology = (rank, world_size, worker, num_workers)
        self.transform = transform
        self._progress: dict[int, int] = {}

    # ---- sizes and plan -------------------------------------------------------------------------
    def __len__(self) -> int:
        """Items in one epoch over all ranks and workers."""
        return sum(s[1] if self.mode == "samples" else s[2] for s in self.shards)

    def topology(self) -> tuple[int, int, int, int]:
        """(rank, world_size, worker, num_workers): explicit values win over what torch/env say.

        With a torch DataLoader pass `num_workers` equal to the loader's, so that `state_dict()` in the
        main process describes the same slots the workers read.
        """
        d = _default_topology()
        t = tuple(d[i] if v is None else int(v) for i, v in enumerate(self._topology))
        torch = sys.modules.get("torch")
        info = torch.utils.data.get_worker_info() if torch is not None else None
        if info is not None and self._topology[3] is not None and info.num_workers != t[3]:
            raise ValueError(f"stream built for num_workers={t[3]} but the DataLoader runs {info.num_workers} workers")
        return t  # type: ignore[return-value]

    def shard_order(self, epoch: int | None = None) -> list[int]:
        epoch = self.epoch if epoch is None else epoch
        order = list(range(len(self.shards)))
        if self.shuffle:
            order = [int(i) for i in np.random.default_rng([self.seed, epoch, 0x5A4D]).permutation(len(order))]
        return order

    def slot_range(self, slot: int, slots: int) -> tuple[int, int]:
        n = len(self)
        return n * slot // slots, n * (slot + 1) // slots

    def _plan(self, lo: int, hi: int) -> Iterator[tuple[int, int, int]]:
        """(shard index, items to skip, items to take) covering the global range [lo, hi)."""
        pos = 0
        for i in self.shard_order():
            c = self.shards[i][1] if self.mode == "samples" else self.shards[i][2]
            a, b = max(pos, lo), min(pos + c, hi)
            if a < b:
                yield i, a - pos, b - a
            pos += c

    # ---- reading --------------------------------------------------------------------------------
    def _items(self, slot: int, slots: int) -> Iterator[StreamSample]:
        lo, hi = self.slot_range(slot, slots)
        for si, skip, take in self._plan(lo, hi):
            path = self.shards[si][0]
            seen = taken = 0
            for raw in iter_raw(path):
                n_q = int(raw.header["qa_pairs"]) if self.mode == "qa" else 1
                if seen + n_q <= skip:
                    seen += n_q
                    continue
                for k in range(n_q):
                    if seen < skip:
                        seen += 1
                        continue
                    if taken == take:
                        break
                    seen += 1
                    taken += 1
                    yield (StreamSample(raw, path.name) if self.mode == "samples"
                           else StreamQA(raw, path.name, qa_index=k))
                if taken == take:
                    break
            if taken != take:
                raise ShardError(path, f"holds fewer items than the index says ({seen} read, needed {skip + take})")

    def _shuffled(self, items: Iterator[StreamSample], slot: int) -> Iterator[StreamSample]:
        if not self.shuffle or self.buffer_size <= 1:
            yield from items
            return
        rng = np.random.default_rng([self.seed, self.epoch, slot, 0xB0F])
        buf: list[StreamSample] = []
        for it in items:
            if len(buf) < self.buffer_size:
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

    def __iter__(self) -> Iterator[Any]:
        rank, world, worker, workers = self.topology()
        slots = world * workers
        slot = rank * workers + worker
        if not (0 <= slot < slots):
            raise ValueError(f"rank {rank}/{world}, worker {worker}/{workers} is not a valid slot")
        start = self._progress.get(slot, 0)
        for idx, item in enumerate(self._shuffled(self._items(slot, slots), slot)):
            if idx < start:
                continue
            item.slot, item.index = slot, idx
            self._progress[slot] = idx + 1
            if self.transform is None:
                yield item
            else:
                out = self.transform(item)
                if isinstance(out, dict):
                    out.setdefault("__position__", (slot, idx))
                yield out

    # ---- epochs and resume ----------------------------------------------------------------------
    def set_epoch(self, epoch: int) -> None:
        """Start epoch `epoch` (a new order) from its beginning."""
        self.epoch = int(epoch)
        self._progress = {}

    def record(self, positions) -> None:
        """Note items consumed by the training loop: (slot, index) pairs or items with `.position`.

        Needed with dataloader workers, whose progress the main process does not see.
        """
        for p in positions:
            slot, idx = p.position if hasattr(p, "position") else (p["__position__"] if isinstance(p, dict) else p)
            self._progress[int(slot)] = max(self._progress.get(int(slot), 0), int(idx) + 1)

    def state_dict(self) -> dict:
        rank, world, worker, workers = self.topology()
        return {"version": STATE_VERSION, "seed": self.seed, "epoch": self.epoch, "mode": self.mode,
                "shuffle": self.shuffle, "buffer_size": self.buffer_size, "slots": world * workers,
                "items": len(self), "progress": {str(k): v for k, v in sorted(self._progress.items())}}

    def load_state_dict(self, state: dict) -> None:
        if state.get("version") != STATE_VERSION:
            raise ValueError(f"stream state version {state.get('version')!r} not supported")
        rank, world, worker, workers = self.topology()
        for key, mine in (("mode", self.mode), ("shuffle", self.shuffle), ("buffer_size", self.buffer_size),
                          ("slots", world * workers), ("items", len(self))):
            if state.get(key) != mine:
                raise ValueError(f"cannot resume: state has {key}={state.get(key)!r}, this stream has {mine!r}")
        self.seed, self.epoch = int(state["seed"]), int(state["epoch"])
        self._progress = {int(k): int(v) for k, v in state["progress"].items()}

    # ---- torch ----------------------------------------------------------------------------------
    @classmethod
    def torch(cls, *args, **kwargs) -> "ShardStream":
        """The same stream as a `torch.utils.data.IterableDataset` (needs torch)."""
        return _torch_class()(*args, **kwargs)


_TORCH_CLASS = None


def _torch_class():
    global _TORCH_CLASS
    if _TORCH_CLASS is None:
        from torch.utils.data import IterableDataset

        class TorchShardStream(ShardStream, IterableDataset):
            """ShardStream as a torch IterableDataset (rank and worker come from torch)."""

        _TORCH_CLASS = TorchShardStream
    return _TORCH_CLASS


def __getattr__(name: str):
    if name == "TorchShardStream":
        return _torch_class()
    raise AttributeError(name)


def qa_stream(source, **kwargs) -> ShardStream:
    """Shorthand for a stream over QA pairs."""
    return ShardStream(source, mode="qa", **kwargs)
