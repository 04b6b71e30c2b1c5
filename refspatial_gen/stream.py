"""Streaming shards into training jobs: exactly once per epoch across ranks and workers, resumable.

Why this design:
- The epoch's global order is fixed by (seed, epoch): shards are permuted, items (samples, or QA pairs
  in QA mode) follow in file order. Each reader slot (rank x dataloader worker) takes one contiguous
  share of that order (sizes differ by at most one), so every item is read exactly once and a slot
  opens only the shards its share touches. The arithmetic lives in `stream_layout` (no file access).
- A bounded shuffle buffer, seeded by (seed, epoch, slot), mixes items within a slot.
- Resume: a slot's position is the number of items it has handed out; the stream is deterministic, so
  `load_state_dict` replays the slot up to that count without decoding pixels and goes on: no repeats,
  no gaps. A state names its rank, world size and workers and is refused by any other topology;
  `load_elastic_state(all ranks' states)` instead re-splits the rest of the epoch over the new one.
- As a torch `IterableDataset` (`ShardStream.torch`): picklable (spawn/forkserver workers), the epoch
  is held in shared memory so `set_epoch` reaches persistent workers, and every `iter()` starts a
  full pass of the current epoch (only the first pass after a resume skips what was consumed).
- Every shard is checked against index.json before its first item (shards.trust); a damaged shard
  raises ShardError, or with `on_error="skip"` is skipped, warned about and counted in `skipped`.
- Images are decoded lazily: items keep the encoded message bytes until `.rgb()` / `.depth()` is called.

torch is optional: `ShardStream` is a plain iterable; `ShardStream.torch(...)` gives the torch dataset.
"""

from __future__ import annotations

import hashlib
import os
import sys
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from refspatial_gen import stream_layout as lay
from refspatial_gen.shards.index import read_index
from refspatial_gen.shards.reader import ShardError, iter_raw
from refspatial_gen.stream_items import StreamQA, StreamSample

STATE_VERSION = 2


def _resolve_shards(source: str | Path | Sequence[str | Path]) -> tuple[list[tuple[Path, int, int]], str]:
    """([(path, samples, qa_pairs)] in index order or as given, fingerprint of the dataset)."""
    h = hashlib.sha256()
    if isinstance(source, (str, Path)) and Path(source).is_dir():
        d = Path(source)
        rows = read_index(d)["shards"]
        for s in rows:
            h.update(f"{s['name']}\0{s['samples']}\0{s['qa_pairs']}\0{s.get('sha256')}\n".encode())
        return [(d / s["name"], int(s["samples"]), int(s["qa_pairs"])) for s in rows], h.hexdigest()[:16]
    paths = [Path(source)] if isinstance(source, (str, Path)) else [Path(p) for p in source]
    out = []
    for p in paths:
        n = q = 0
        for raw in iter_raw(p, keep_topic=lambda t: False):
            n += 1
            q += int(raw.header["qa_pairs"])
        out.append((p, n, q))
        h.update(f"{p.name}\0{n}\0{q}\0{p.stat().st_size}\n".encode())
    return out, h.hexdigest()[:16]


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


def _positions_of(batch) -> list[tuple[int, int]]:
    """(slot, index) pairs from what a DataLoader returns: items, dicts with `__position__`, a default-
    collated dict (whose `__position__` is [slots, indices] tensors), or plain pairs."""
    if isinstance(batch, dict):
        pos = batch["__position__"]
        if hasattr(pos, "tolist"):  # a (batch, 2) tensor
            pos = pos.tolist()
        if len(pos) == 2 and all(hasattr(p, "tolist") for p in pos):  # default_collate: [slots, indices]
            return list(zip(pos[0].tolist(), pos[1].tolist()))
        return [(int(a), int(b)) for a, b in pos]
    out = []
    for p in batch:
        if hasattr(p, "position"):
            p = p.position
        elif isinstance(p, dict):
            p = p["__position__"]
        out.append((int(p[0]), int(p[1])))
    return out


class ShardStream:
    """Iterate samples (`mode="samples"`) or QA pairs (`mode="qa"`) of a shard directory or file list.

    rank/world_size/worker/num_workers default to torch.distributed, the dataloader worker info, or
    the RANK / WORLD_SIZE environment variables. With a torch DataLoader, pass the loader's
    `num_workers` so that `state_dict()` in the main process describes the slots the workers read.
    `transform(item)` runs in the reader (dataloader worker), the place to decode pixels; it must be
    picklable (a module-level function) for spawn/forkserver workers. `on_error="skip"` skips (and
    counts in `skipped`) a shard that fails its integrity check instead of raising.
    """

    def __init__(self, source: str | Path | Sequence[str | Path], *, mode: str = "samples", shuffle: bool = True,
                 seed: int = 0, epoch: int = 0, buffer_size: int = 256, rank: int | None = None,
                 world_size: int | None = None, worker: int | None = None, num_workers: int | None = None,
                 transform: Callable[[StreamSample], Any] | None = None, on_error: str = "raise") -> None:
        if mode not in ("samples", "qa"):
            raise ValueError(f"mode must be 'samples' or 'qa', got {mode!r}")
        if on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {on_error!r}")
        self.source = source
        self.shards, self.fingerprint = _resolve_shards(source)
        self.mode, self.shuffle, self.seed = mode, shuffle, int(seed)
        self.buffer_size = max(1, int(buffer_size))
        self._topology = (rank, world_size, worker, num_workers)
        self.transform, self.on_error = transform, on_error
        self._epoch_cell = None  # a shared-memory tensor in the torch variant
        self._epoch = int(epoch)
        self._consumed: dict[int, int] = {}  # items handed to the trainer this epoch, per slot
        self._resume: dict[int, int] = {}  # where the first pass of `_resume_epoch` starts, per slot
        self._resume_epoch: int | None = None
        self._done: lay.Ranges = []  # positions used up before an elastic re-split of `_done_epoch`
        self._done_epoch: int | None = None
        self._resplit = 0
        self.skipped: dict[str, str] = {}

    # ---- sizes and plan -------------------------------------------------------------------------
    @property
    def epoch(self) -> int:
        return int(self._epoch_cell.item()) if self._epoch_cell is not None else self._epoch

    def total_items(self) -> int:
        """Items in one full epoch over all ranks and workers."""
        return sum(s[1] if self.mode == "samples" else s[2] for s in self.shards)

    def __len__(self) -> int:
        """Items this rank reads in the current epoch (all its workers together; after an elastic
        re-split, its share of what was left)."""
        rank, world, _, _ = self.topology()
        return lay.count(lay.slot_ranges(self.total_items(), self._layout()[0], rank, world))

    def topology(self) -> tuple[int, int, int, int]:
        """(rank, world_size, worker, num_workers): explicit values win over what torch/env say."""
        d = _default_topology()
        t = tuple(d[i] if v is None else int(v) for i, v in enumerate(self._topology))
        torch = sys.modules.get("torch")
        info = torch.utils.data.get_worker_info() if torch is not None else None
        if info is not None and self._topology[3] is not None and info.num_workers != t[3]:
            raise ValueError(f"stream built for num_workers={t[3]} but the DataLoader runs {info.num_workers} workers")
        return t  # type: ignore[return-value]

    def shard_order(self, epoch: int | None = None) -> list[int]:
        import numpy as np

        epoch = self.epoch if epoch is None else epoch
        order = list(range(len(self.shards)))
        if self.shuffle:
            order = [int(i) for i in np.random.default_rng([self.seed, epoch, 0x5A4D]).permutation(len(order))]
        return order

    def _layout(self) -> tuple[lay.Ranges, int]:
        """(positions already used up, re-split count) of the current epoch."""
        return (self._done, self._resplit) if self._done_epoch == self.epoch else ([], 0)

    def _order_kw(self) -> dict:
        return {"seed": self.seed, "epoch": self.epoch, "resplit": self._layout()[1], "shuffle": self.shuffle,
                "buffer_size": self.buffer_size}

    # ---- reading --------------------------------------------------------------------------------
    def _items(self, ranges: lay.Ranges) -> Iterator[StreamSample]:
        """The items at the given global positions of this epoch, in order."""
        pos = 0
        for si in self.shard_order():
            c = self.shards[si][1] if self.mode == "samples" else self.shards[si][2]
            windows = [(max(a, pos) - pos, min(b, pos + c) - pos) for a, b in ranges if a < pos + c and b > pos]
            if windows:
                yield from self._read(si, windows)
            pos += c

    def _read(self, si: int, windows: lay.Ranges) -> Iterator[StreamSample]:
        path = self.shards[si][0]
        need, last = lay.count(windows), windows[-1][1]
        k = taken = wi = 0
        try:
            for raw in iter_raw(path):
                n_q = int(raw.header["qa_pairs"]) if self.mode == "qa" else 1
                for q in range(n_q):
                    while wi < len(windows) and windows[wi][1] <= k + q:
                        wi += 1
                    if wi < len(windows) and k + q >= windows[wi][0]:
                        taken += 1
                        yield StreamSample(raw, path.name) if self.mode == "samples" else StreamQA(raw, path.name, qa_index=q)
                k += n_q
                if k >= last:
                    break
            if taken != need:
                raise ShardError(path, f"holds fewer items than the index says ({k} read, needed {last})")
        except ShardError as e:
            if self.on_error != "skip":
                raise
            self.skipped[path.name] = e.reason
            warnings.warn(f"skipping shard {e}", stacklevel=2)

    def __iter__(self) -> Iterator[Any]:
        rank, world, worker, workers = self.topology()
        slots, slot = world * workers, rank * workers + worker
        if not (0 <= slot < slots):
            raise ValueError(f"rank {rank}/{world}, worker {worker}/{workers} is not a valid slot")
        epoch = self.epoch
        start = self._resume.pop(slot, 0) if self._resume_epoch == epoch else 0  # only the first pass resumes
        self._consumed[slot] = start
        ranges = lay.slot_ranges(self.total_items(), self._layout()[0], slot, slots)
        items = self._items(ranges)
        kw = self._order_kw()
        if kw["shuffle"] and self.buffer_size > 1:
            items = lay.shuffle_buffer(items, lay.slot_rng(self.seed, epoch, slot, kw["resplit"]), self.buffer_size)
        for idx, item in enumerate(items):
            if idx < start:
                continue
            item.slot, item.index = slot, idx
            self._consumed[slot] = idx + 1
            if self.transform is None:
                yield item
            else:
                out = self.transform(item)
                if isinstance(out, dict):
                    out.setdefault("__position__", (slot, idx))
                yield out

    # ---- epochs and resume ----------------------------------------------------------------------
    def set_epoch(self, epoch: int) -> None:
        """Start epoch `epoch` (a new order) from its beginning; reaches persistent dataloader workers."""
        self._epoch = int(epoch)
        if self._epoch_cell is not None:
            self._epoch_cell.fill_(int(epoch))
        self._consumed, self._resume, self._resume_epoch = {}, {}, None

    def record(self, batch) -> None:
        """Note items consumed by the training loop (needed with dataloader workers, whose progress the
        main process does not see): a batch from any collate (see `_positions_of`) or (slot, index) pairs."""
        rank, world, _, workers = self.topology()
        for slot, idx in _positions_of(batch):
            if not rank * workers <= int(slot) < (rank + 1) * workers:
                raise ValueError(f"item from slot {slot} is not one of rank {rank}'s {workers} worker slots: "
                                 f"build the stream with num_workers equal to the DataLoader's")
            self._consumed[int(slot)] = max(self._consumed.get(int(slot), 0), int(idx) + 1)

    def state_dict(self) -> dict:
        rank, world, _, workers = self.topology()
        done, resplit = self._layout()
        return {"version": STATE_VERSION, "seed": self.seed, "epoch": self.epoch, "mode": self.mode,
                "shuffle": self.shuffle, "buffer_size": self.buffer_size, "items": self.total_items(),
                "dataset": self.fingerprint, "rank": rank, "world_size": world, "num_workers": workers,
                "slots": world * workers, "done": [list(r) for r in done], "resplit": resplit,
                "progress": {str(k): v for k, v in sorted(self._consumed.items())}}

    def _check_same_data(self, state: dict) -> None:
        if not isinstance(state, dict) or state.get("version") != STATE_VERSION:
            raise ValueError(f"stream state version {state.get('version') if isinstance(state, dict) else state!r} "
                             f"not supported (this code writes {STATE_VERSION})")
        for key, mine in (("mode", self.mode), ("shuffle", self.shuffle), ("buffer_size", self.buffer_size),
                          ("items", self.total_items()), ("dataset", self.fingerprint)):
            if state.get(key) != mine:
                raise ValueError(f"cannot resume: state has {key}={state.get(key)!r}, this stream has {mine!r}")

    def _apply(self, state: dict, done: lay.Ranges, resplit: int, progress: dict[int, int]) -> None:
        self.seed = int(state["seed"])
        self.set_epoch(int(state["epoch"]))
        self._done, self._done_epoch, self._resplit = done, self.epoch, resplit
        self._resume, self._resume_epoch, self._consumed = dict(progress), self.epoch, dict(progress)

    def load_state_dict(self, state: dict) -> None:
        """Resume this rank from its own state; a state of another rank, world size or worker count is
        refused (use `load_elastic_state` with every rank's state to change the topology)."""
        self._check_same_data(state)
        rank, world, _, workers = self.topology()
        if (state.get("rank"), state.get("world_size"), state.get("num_workers")) != (rank, world, workers):
            raise ValueError(f"cannot resume: the state is from rank {state.get('rank')} of {state.get('world_size')} "
                             f"with {state.get('num_workers')} workers, this stream is rank {rank} of {world} with "
                             f"{workers}; load each rank's own state, or pass every rank's state to "
                             f"load_elastic_state() to re-split the rest of the epoch")
        progress = {int(k): int(v) for k, v in state["progress"].items()}
        bad = [s for s in progress if not rank * workers <= s < (rank + 1) * workers]
        if bad:
            raise ValueError(f"cannot resume: the state's progress names slots {bad} outside rank {rank}'s")
        self._apply(state, [tuple(r) for r in state["done"]], int(state["resplit"]), progress)

    def load_elastic_state(self, states: Sequence[dict]) -> None:
        """Resume on any topology from the states of every rank of the previous one: the items they had
        not consumed in their epoch are split afresh over this topology's slots, each read exactly once."""
        states = [states] if isinstance(states, dict) else list(states)
        if not states:
            raise ValueError("load_elastic_state needs the state of every rank of the previous run")
        for st in states:
            self._check_same_data(st)
        ref = states[0]
        for key in ("seed", "epoch", "world_size", "num_workers", "done", "resplit"):
            if any(st.get(key) != ref.get(key) for st in states):
                raise ValueError(f"cannot resume: the states disagree on {key} (not from one checkpoint)")
        ranks = sorted(int(st["rank"]) for st in states)
        if ranks != list(range(int(ref["world_size"]))):
            raise ValueError(f"cannot resume elastically: states of ranks {ranks} given, the run had "
                             f"{ref['world_size']} ranks (every rank's state is needed)")
        progress = {int(k): int(v) for st in states for k, v in st["progress"].items()}
        done = [tuple(r) for r in ref["done"]]
        used = lay.consumed(int(ref["items"]), done, int(ref["slots"]), progress, seed=int(ref["seed"]),
                            epoch=int(ref["epoch"]), resplit=int(ref["resplit"]), shuffle=bool(ref["shuffle"]),
                            buffer_size=int(ref["buffer_size"]))
        self._apply(ref, used, int(ref["resplit"]) + 1, {})

    # ---- torch ----------------------------------------------------------------------------------
    @classmethod
    def torch(cls, *args, **kwargs) -> "ShardStream":
        """The same stream as a `torch.utils.data.IterableDataset` (needs torch)."""
        return _torch_class()(*args, **kwargs)


_TORCH_CLASS = None


def _torch_class():
    global _TORCH_CLASS
    if _TORCH_CLASS is None:
        import torch
        from torch.utils.data import IterableDataset

        class TorchShardStream(ShardStream, IterableDataset):
            """ShardStream as a torch IterableDataset; its epoch lives in shared memory so that
            `set_epoch` in the main process reaches persistent dataloader workers."""

            def __init__(self, *args, **kwargs) -> None:
                super().__init__(*args, **kwargs)
                self._epoch_cell = torch.tensor(self._epoch, dtype=torch.int64).share_memory_()

        TorchShardStream.__module__, TorchShardStream.__qualname__ = __name__, "TorchShardStream"  # picklable by name
        _TORCH_CLASS = TorchShardStream
    return _TORCH_CLASS


def __getattr__(name: str):
    if name == "TorchShardStream":
        return _torch_class()
    raise AttributeError(name)


def qa_stream(source, **kwargs) -> ShardStream:
    """Shorthand for a stream over QA pairs."""
    return ShardStream(source, mode="qa", **kwargs)
