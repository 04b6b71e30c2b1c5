"""One typed record per sample, shared by the WebDataset JSON and the Hugging Face Parquet export.

Why typed: columnar readers (Arrow, Hugging Face `datasets`, Ray Data) infer one type per field, and a
field that is an object in one record and a number or list in another ("cannot mix struct and
non-struct") makes the whole dataset unloadable. Free-form parts of a sample (answer_struct, program,
key_steps, meta, frame metadata, graphs) therefore travel as canonical JSON strings (`*_json`); every
other field has one fixed type, declared below as `datasets.Features` for the Parquet export.
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.core.serialize import dumps
from refspatial_gen.shards.format import RawSample

RECORD_VERSION = 1


def _js(obj: Any) -> str:
    return dumps(obj).decode("utf-8")


def strip_tokens(text: str) -> str:
    """Question/answer text without <image>/<depth> tokens (RefSpatial trainers add their own)."""
    return str(text).replace("<image>", "").replace("<depth>", "").strip()


def qa_record(qa: dict, frame_ids: list[str]) -> dict:
    """A QA pair with fixed field types; `views` are the positions of its frames in the sample."""
    views = [frame_ids.index(f) for f in qa.get("frame_ids", []) if f in frame_ids] or [0]
    w, h = (list(qa.get("image_size") or [0, 0]) + [0, 0])[:2]
    return {
        "qa_id": str(qa["qa_id"]),
        "family": str(qa["family"]),
        "template": str(qa.get("template", "")),
        "question": str(qa["question"]),
        "answer": str(qa["answer"]),
        "steps": int(qa.get("steps", 1)),
        "relations": [str(r) for r in qa.get("relations") or []],
        "frame_ids": [str(f) for f in qa.get("frame_ids") or []],
        "views": views,
        "image_width": int(w),
        "image_height": int(h),
        "trace": str(qa.get("trace") or ""),
        "checks": [str(c) for c in qa.get("checks") or []],
        "targets": [int(t) for t in qa.get("targets") or []],
        "answer_struct_json": _js(qa.get("answer_struct") or {}),
        "key_steps_json": _js(qa.get("key_steps") or []),
        "program_json": _js(qa.get("program") or []),
    }


def conversations(qa: list[dict]) -> list[dict]:
    """Human/gpt turns over a sample's QA pairs, without <image>/<depth> tokens (the trainer adds them)."""
    turns = []
    for q in qa:
        turns.append({"from": "human", "value": strip_tokens(q["question"])})
        turns.append({"from": "gpt", "value": strip_tokens(q["answer"])})
    return turns


def sample_record(raw: RawSample) -> dict:
    """Everything but pixels of one sample, typed (see the module docstring)."""
    h = raw.header
    frame_ids = [str(f) for f in h["frame_ids"]]
    qa = raw.qa_json()
    meta = h.get("meta") or {}
    return {
        "record_version": RECORD_VERSION,
        "sample_id": str(h["sample_id"]),
        "unit_key": str(h["unit_key"]),
        "source": str(meta.get("source", "")),
        "views": int(h["views"]),
        "frame_ids": frame_ids,
        "image_format": str(h.get("image_format", "")),
        "qa": [qa_record(q, frame_ids) for q in qa],
        "conversations": conversations(qa),
        "meta_json": _js(meta),
        "frames_json": _js([raw.frame_meta(v) for v in range(int(h["views"]))]),
        "graphs_json": _js(raw.graphs_json()),
    }


def hf_features():
    """The Parquet export's declared `datasets.Features` (needs the `datasets` extra).

    images: the stored JPEG/PNG bytes of each view; depth: each view's metric depth in metres as a
    32-bit float TIFF (`Image(mode="F")`, lossless; 0 = unknown); conversations: human/gpt turns.
    """
    from datasets import Features, Image, List, Value

    s, i32 = Value("string"), Value("int32")
    qa = {
        "qa_id": s,
        "family": s,
        "template": s,
        "question": s,
        "answer": s,
        "steps": i32,
        "relations": List(s),
        "frame_ids": List(s),
        "views": List(i32),
        "image_width": i32,
        "image_height": i32,
        "trace": s,
        "checks": List(s),
        "targets": List(Value("int64")),
        "answer_struct_json": s,
        "key_steps_json": s,
        "program_json": s,
    }
    return Features(
        {
            "record_version": i32,
            "sample_id": s,
            "unit_key": s,
            "source": s,
            "views": i32,
            "frame_ids": List(s),
            "image_format": s,
            "images": List(Image()),
            "depth": List(Image(mode="F")),
            "conversations": List({"from": s, "value": s}),
            "qa": List(qa),
            "meta_json": s,
            "frames_json": s,
            "graphs_json": s,
        }
    )
