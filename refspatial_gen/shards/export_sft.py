"""`export --format sft`: the RefSpatial layout for supervised fine-tuning with reasoning (cold start).

The same files and loader rules as `--format refspatial` (image/, depth/, one JSON list per family,
checked by `check_roborefer_layout`), with two differences:
- the answer turn of a QA pair that has a reasoning trace is the full trace
  `<think>[Position] [the cup]: (0.510, 0.255)\n...</think><answer>[(0.510, 0.255)]</answer>`, so the model
  learns to write its key steps before the answer (single-step pairs keep their plain answer);
- every record carries `split`, and only the requested splits are written (default: train; a dataset
  whose index has no splits is written whole).
File names, exclusive writes and the check against the shards are the RefSpatial export's
(export_files.StemRegistry / write_new, export_refspatial.check_export); `shards.export` writes the
whole folder atomically.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from refspatial_gen.run.splits import keep_sample, sample_split, splits_of_samples
from refspatial_gen.shards import export_refspatial
from refspatial_gen.shards.export_files import StemRegistry, write_new
from refspatial_gen.shards.export_refspatial import check_roborefer_layout, export_sample, safe_name
from refspatial_gen.shards.format import RawSample


def export_sft(
    raws: Iterable[RawSample], out: Path | str, *, splits: Iterable[str] | None = ("train",), with_depth: bool = True
) -> dict:
    """Write the layout; returns {"records": {family: n}, "qa_pairs", "reasoning_pairs", "samples", "by_split"}."""
    out = Path(out)
    (out / "image").mkdir(parents=True, exist_ok=True)
    if with_depth:
        (out / "depth").mkdir(parents=True, exist_ok=True)
    scene_map = splits_of_samples(raws)
    wanted = None if splits is None else tuple(splits)
    by_family: dict[str, list[dict]] = {}
    n_qa = n_reason = n_samples = 0
    by_split: dict[str, int] = {}
    stems = StemRegistry()
    for raw in raws:
        h = raw.header
        frames = [raw.frame_meta(v) for v in range(int(h["views"]))]
        split = sample_split(scene_map, frames, h["sample_id"])
        if not keep_sample(split, wanted):
            continue
        n_samples += 1
        for fam, recs in export_sample(raw, out, with_depth, stems).items():
            for rec in recs:
                rec["split"] = split
                for i, think in enumerate(rec.get("think") or []):
                    rec["conversations"][2 * i + 1]["value"] = think["trace"]
                    n_reason += 1
                n_qa += len(rec["conversations"]) // 2
                by_split[split] = by_split.get(split, 0) + len(rec["conversations"]) // 2
            by_family.setdefault(fam, []).extend(recs)
    for fam, recs in sorted(by_family.items()):
        write_new(
            out / f"{safe_name(fam)}.json", json.dumps(recs, ensure_ascii=False, indent=1, sort_keys=True).encode()
        )
    if by_family:
        errors = check_roborefer_layout(out)
        if errors:
            raise ValueError(f"{out}: the SFT export breaks {len(errors)} RoboRefer loader rule(s), first: {errors[0]}")
    return {
        "records": {f: len(r) for f, r in sorted(by_family.items())},
        "qa_pairs": n_qa,
        "reasoning_pairs": n_reason,
        "samples": n_samples,
        "by_split": dict(sorted(by_split.items())),
    }


def check_export(out: Path, raws: Iterable[RawSample]) -> list[str]:
    """The RefSpatial export's check (loader rules, image and depth bytes against the shards), plus: the
    answer turn of every reasoning pair is its trace. An export whose splits hold no QA pair is empty."""
    out = Path(out)
    if not any(out.glob("*.json")):
        left = [p.name for d in ("image", "depth") if (out / d).is_dir() for p in (out / d).iterdir()]
        return [f"{out}: {len(left)} image/depth files but no records"] if left else []
    problems = export_refspatial.check_export(out, raws)
    for f in sorted(out.glob("*.json")):
        try:
            recs = json.loads(f.read_text(encoding="utf-8"))
        except ValueError:
            continue  # reported above
        for rec in recs if isinstance(recs, list) else []:
            conv = rec.get("conversations") or []
            for i, think in enumerate(rec.get("think") or []):
                if 2 * i + 1 >= len(conv) or conv[2 * i + 1].get("value") != think.get("trace"):
                    problems.append(f"{f.name}:{rec.get('id')}: answer turn {2 * i + 1} is not its reasoning trace")
    return problems
