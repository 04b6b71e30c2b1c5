"""Export one JSON line per QA pair, with its trace and key steps (for reinforcement fine-tuning).

Each line: {id, sample_id, image: [RefSpatial image names], image_size, family, template, question,
answer, answer_struct, steps, relations, trace, key_steps, targets}. Images are written beside it in the
same `image/` layout as the RefSpatial export (stored bytes copied), so a reward function can load them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable

from refspatial_gen.shards.export_refspatial import _EXT, safe_name
from refspatial_gen.shards.format import RawSample

_FIELDS = ("family", "template", "question", "answer", "answer_struct", "steps", "relations", "trace",
           "key_steps", "targets", "image_size", "checks")


def export_jsonl(raws: Iterable[RawSample], out: Path | str, *, images: bool = True) -> dict:
    """Write `out/qa.jsonl` (+ `out/image/`); returns {"qa_pairs": n, "samples": m}."""
    out = Path(out)
    (out / "image").mkdir(parents=True, exist_ok=True)
    n = m = 0
    with open(out / "qa.jsonl", "w", encoding="utf-8") as f:
        for raw in raws:
            h = raw.header
            base = safe_name(h["sample_id"])
            frame_ids = list(h["frame_ids"])
            names = []
            for v in range(int(h["views"])):
                data, fmt = raw.image_bytes(v)
                names.append(f"{base}_v{v}.{_EXT.get(fmt, fmt)}")
                if images and not (out / "image" / names[-1]).exists():
                    (out / "image" / names[-1]).write_bytes(data)
            for qa in raw.qa_json():
                vs = [frame_ids.index(fid) for fid in qa["frame_ids"] if fid in frame_ids] or [0]
                line = {"id": qa["qa_id"], "sample_id": h["sample_id"], "image": [names[v] for v in vs],
                        **{k: qa.get(k) for k in _FIELDS}}
                f.write(json.dumps(line, ensure_ascii=False, sort_keys=True) + "\n")
                n += 1
            m += 1
    return {"qa_pairs": n, "samples": m}
