"""Picklable transforms and a torchrun script body for the stream's DataLoader tests (spawn and
forkserver workers import these by name, so they cannot be lambdas in the test module)."""

from __future__ import annotations


def item_id(item) -> dict:
    """Sample id (or QA id) plus something numeric, so the default collate builds tensors too."""
    key = item.qa_id if hasattr(item, "qa_id") else item.sample_id
    return {"id": key, "qa": len(item.qa), "h": int(item.rgb(0).shape[0])}


def ids_of(batch) -> list[str]:
    """Ids from a default-collated batch (a dict of lists/tensors) or a list of dicts."""
    return list(batch["id"]) if isinstance(batch, dict) else [b["id"] for b in batch]
