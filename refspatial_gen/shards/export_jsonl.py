"""Export one JSON line per QA pair, with its trace and key steps (for reinforcement fine-tuning).

Each line: {id, sample_id, image: [image names], image_size, family, template, question, answer,
answer_struct, steps, relations, trace, key_steps, targets, checks}. Images are written beside it in
the same `image/` layout as the RefSpatial export (stored bytes copied), so a reward function can load
them; a visual-choice pair (one whose answer_struct has `marks`) names the marked copies of its views,
since its question is about the drawn labels.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from refspatial_gen.shards.export_files import (
    EXT,
    StemRegistry,
    check_image_refs,
    stored_image_hashes,
    view_name,
    write_new,
)
from refspatial_gen.shards.export_refspatial import marked_name
from refspatial_gen.shards.format import RawSample
from refspatial_gen.shards.marks import marked_pngs

_FIELDS = (
    "family",
    "template",
    "question",
    "answer",
    "answer_struct",
    "steps",
    "relations",
    "trace",
    "key_steps",
    "targets",
    "image_size",
    "checks",
)


def export_jsonl(raws: Iterable[RawSample], out: Path | str, *, images: bool = True) -> dict:
    """Write `out/qa.jsonl` (+ `out/image/`); returns {"qa_pairs": n, "samples": m}."""
    out = Path(out)
    (out / "image").mkdir(parents=True, exist_ok=True)
    stems = StemRegistry()
    n = m = 0
    with open(out / "qa.jsonl", "x", encoding="utf-8") as f:
        for raw in raws:
            h = raw.header
            stem = stems.claim(h["sample_id"])
            frame_ids = list(h["frame_ids"])
            names = []
            for v in range(int(h["views"])):
                data, fmt = raw.image_bytes(v)
                names.append(view_name(stem, v, EXT.get(fmt, fmt)))
                if images:
                    write_new(out / "image" / names[-1], data)
            for qi, qa in enumerate(raw.qa_json()):
                vs = [frame_ids.index(fid) for fid in qa["frame_ids"] if fid in frame_ids] or [0]
                refs = [names[v] for v in vs]
                for v, png in marked_pngs(raw, qa).items():
                    mname = marked_name(stem, v, qi)
                    if images:
                        write_new(out / "image" / mname, png)
                    if v in vs:
                        refs[vs.index(v)] = mname
                line = {
                    "id": qa["qa_id"],
                    "sample_id": h["sample_id"],
                    "image": refs,
                    **{k: qa.get(k) for k in _FIELDS},
                }
                f.write(json.dumps(line, ensure_ascii=False, sort_keys=True) + "\n")
                n += 1
            m += 1
    return {"qa_pairs": n, "samples": m}


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """Every line parses and names images that hold what the shards store for its sample's views
    (marked copies for visual-choice pairs); the line count equals the QA pairs in the shards."""
    out = Path(out)
    n_qa = [0]

    def count(raw: RawSample, stem: str, v: int) -> None:
        if v == 0:
            n_qa[0] += int(raw.header["qa_pairs"])

    stored = stored_image_hashes(raws, count)
    refs, problems = [], []
    lines = (out / "qa.jsonl").read_text(encoding="utf-8").splitlines()
    for i, text in enumerate(lines):
        try:
            refs += json.loads(text)["image"]
        except (ValueError, KeyError, TypeError) as e:
            problems.append(f"{out / 'qa.jsonl'}:{i + 1}: not a QA line ({e})")
    if len(lines) != n_qa[0]:
        problems.append(f"{out / 'qa.jsonl'}: {len(lines)} lines for {n_qa[0]} QA pairs in the shards")
    if (out / "image").is_dir() and any((out / "image").iterdir()):
        problems += check_image_refs(out / "image", refs, stored, str(out / "qa.jsonl"))
    return problems
