"""Where and how models run: device, threads, determinism, and loading each model once per worker.

Byte-identical output across worker counts needs every model call to give the same numbers whichever
worker makes it. On CPU that holds for a fixed thread count (the recipe's `threads`) and fixed batches
(images are batched in fixed blocks of the sorted image list, never by arrival). On a GPU it needs, in
addition, deterministic kernels (set here: `torch.use_deterministic_algorithms`, cuDNN benchmark off, TF32
off, `CUBLAS_WORKSPACE_CONFIG=:4096:8` set before CUDA starts) and the same GPU model, driver, CUDA and
torch versions; across different GPUs, share the perception cache instead (a cached output is reused
as is). docs/perception.md says the same.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Runtime:
    device: str  # "cpu" | "cuda"
    threads: int
    batch_size: int


def make_runtime(cfg: dict[str, Any]) -> Runtime:
    """The runtime a normalised perception section asks for (`device: auto` -> cuda when torch sees one)."""
    dev = cfg.get("device", "auto")
    if dev == "auto":
        dev = "cuda" if _cuda_available() else "cpu"
    return Runtime(dev, int(cfg.get("threads", 1)), int(cfg.get("batch_size", 1)))


def _cuda_available() -> bool:
    try:
        import torch
    except ImportError:
        return False
    return bool(torch.cuda.is_available())


def setup_torch(rt: Runtime) -> None:
    """Threads and deterministic kernels; call before any model runs in this process."""
    if rt.device == "cuda":
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    import torch

    torch.set_num_threads(rt.threads)
    if rt.device == "cuda":
        torch.use_deterministic_algorithms(True, warn_only=True)
        torch.backends.cudnn.benchmark = False
        torch.backends.cudnn.deterministic = True
        torch.backends.cuda.matmul.allow_tf32 = False
        torch.backends.cudnn.allow_tf32 = False


def quiet_transformers() -> None:
    """No progress bars or advisory warnings from transformers in worker logs."""
    from transformers.utils import logging as hf_logging

    hf_logging.set_verbosity_error()
    hf_logging.disable_progress_bar()


def _listing(path: Path) -> tuple:
    files = sorted(p for p in path.rglob("*") if p.is_file() and not p.name.startswith("."))
    return tuple((str(p.relative_to(path)), p.stat().st_size, p.stat().st_mtime_ns) for p in files)


@lru_cache(maxsize=64)
def _hash_listing(path: str, listing: tuple) -> str:
    h = hashlib.sha256()
    for rel, size, _ in listing:
        h.update(f"{rel}\0{size}\0".encode())
        with open(Path(path) / rel, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def folder_hash(path: str | Path) -> str:
    """sha256 over the model folder's files (names, sizes, bytes): what the cache keys on, never the path,
    so a moved or renamed model folder keeps its cached outputs. Computed once per process."""
    p = Path(path).resolve()
    return _hash_listing(str(p), _listing(p))


def read_config(path: str | Path) -> dict[str, Any]:
    import json

    return json.loads((Path(path) / "config.json").read_text(encoding="utf-8"))


@lru_cache(maxsize=16)
def load_model(path: str, rt: Runtime):
    """The family's runner for a model folder, built once per worker process (and runtime)."""
    from refspatial_gen.perception.registry import family_class, family_of

    setup_torch(rt)
    quiet_transformers()
    fam = family_of(read_config(path))
    if fam is None:
        raise ValueError(f"{path}: not a model family refspatial-gen runs")
    return family_class(fam)(path, rt)


def from_folder(path: str, rt: Runtime, model_class: str, processor_class: str | None = "AutoProcessor"):
    """(processor or None, model in eval mode on the runtime's device) from a local folder, never downloaded."""
    import transformers

    proc = None
    if processor_class:
        proc = getattr(transformers, processor_class).from_pretrained(path, local_files_only=True)
    model = getattr(transformers, model_class).from_pretrained(path, local_files_only=True).eval().to(rt.device)
    return proc, model


def to_device(batch: dict[str, Any], device: str) -> dict[str, Any]:
    """Move the tensors of a processor output to the device (other values as they are)."""
    return {k: (v.to(device) if hasattr(v, "to") else v) for k, v in batch.items()}
