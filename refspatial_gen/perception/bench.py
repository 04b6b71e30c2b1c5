"""Per-image time of the photo pipeline: model calls by stage, and everything else ("overhead").

Model time: the published architectures built from their configs with random weights (speed does not
depend on the weights; random_models.py `full=True`, built once under `$REFSPATIAL_BENCH_MODELS`,
default ~/.cache/refspatial-gen/bench-models), run on the shared COCO photos with the cache off; a runner
call counts whole (the processor's resize and normalisation included). Overhead: random boxes rarely
survive lifting, so the rest of a unit is timed with COCO's own boxes and masks standing in for the
detector and segmenter (an oracle) and the image source's geometric depth: decode, filters, hashing,
annotations, lifting, captions, scene graph and QA, per photo. `overhead_over_model` divides the two
(the GPU target, < 20 %, is about that ratio on a GPU; here it is measured on CPU). Model loading and the
first photo are excluded. `python -m refspatial_gen.bench --only perception` runs it.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_FAMILIES = ("grounding-dino", "sam", "depth-anything")


def bench_models_dir() -> Path:
    return Path(os.environ.get("REFSPATIAL_BENCH_MODELS", Path.home() / ".cache" / "refspatial-gen" / "bench-models"))


def ensure_models(families: tuple[str, ...]) -> Path:
    from refspatial_gen.perception.random_models import FOLDERS, build

    root = bench_models_dir()
    for fam in families:
        if not (root / FOLDERS[fam] / "config.json").is_file():
            build(fam, root, full=True)
    return root


def model_times(photos: Path, n: int, families: tuple[str, ...], device: str = "auto") -> dict[str, Any]:
    """Milliseconds per photo by model stage (after one warm-up photo), full-size random models."""
    from refspatial_gen.perception.cache import content_hash
    from refspatial_gen.perception.config import normalise
    from refspatial_gen.perception.pipeline import Item, Perceiver
    from refspatial_gen.perception.random_models import FOLDERS
    from refspatial_gen.sources.image.annotations import list_image_files
    from refspatial_gen.sources.image.source import decode_rgb

    root = ensure_models(families)
    det = "owlv2" if "owlv2" in families else "grounding-dino"
    seg = "sam2" if "sam2" in families else ("sam" if "sam" in families else None)
    dep = next((f for f in ("depth-anything", "depth-pro", "zoedepth") if f in families), None)
    section: dict[str, Any] = {
        "models": str(root),
        "device": device,
        "threads": os.cpu_count() or 1,
        "batch_size": 1,
        "cache": False,
        "filters": {"duplicate_distance": -1, "blur_threshold": 0.0},
        "detector": {"model": FOLDERS[det], "vocabulary": "coco", "threshold": 0.0, "max_detections": 10},
    }
    if seg:
        section["segmenter"] = {"model": FOLDERS[seg]}
    if dep:
        section["depth"] = {"model": FOLDERS[dep]}
    P = Perceiver(normalise(section))
    per: list[dict[str, float]] = []
    for i, f in enumerate(list_image_files(photos / "images")[: n + 1]):
        item = Item(f.stem, content_hash(f.read_bytes()), decode_rgb(f))
        before = dict(P.seconds)
        P.run([item])
        if i:  # the first photo loads the models
            per.append({k: v - before.get(k, 0.0) for k, v in P.seconds.items()})
    m = max(len(per), 1)
    stages = {k: round(1000 * sum(x.get(k, 0.0) for x in per) / m, 1) for k in sorted({k for x in per for k in x})}
    return {
        "images": len(per),
        "device": P.rt.device,
        "threads": P.rt.threads,
        "models": {k: v["model"] for k, v in P.model_meta().items()},
        "model_ms_by_stage": stages,
        "model_ms": round(sum(stages.values()), 1),
    }


class _Oracle:
    """COCO's own boxes and masks as detector and segmenter (bench only: the overhead needs real objects)."""

    def __init__(self, answers: dict[str, list]):
        self.answers = answers

    def detect(self, images, prompts, labels, floor, per_chunk=0):
        from refspatial_gen.perception.boxes import Detection
        from refspatial_gen.perception.cache import array_hash

        return [
            [Detection(b, 0.9, lab) for b, lab, _ in self.answers.get(array_hash(im), []) if lab in labels]
            for im in images
        ]

    def segment(self, images, boxes, multimask=True):
        from refspatial_gen.perception.boxes import iou_matrix
        from refspatial_gen.perception.cache import array_hash

        out = []
        for im, bxs in zip(images, boxes):
            ann = self.answers.get(array_hash(im), [])
            M = iou_matrix(np.array(bxs).reshape(-1, 4), np.array([a[0] for a in ann]).reshape(-1, 4))
            out.append(([ann[int(np.argmax(row))][2] for row in M], [0.9] * len(bxs)))
        return out


def overhead(photos: Path, n: int) -> dict[str, Any]:
    """Milliseconds per photo outside model calls: the unit with oracle detections, graph and QA."""
    import refspatial_gen.perception.pipeline as pipeline
    from refspatial_gen.core.errors import DropUnit
    from refspatial_gen.graph import build_graph
    from refspatial_gen.perception.cache import array_hash
    from refspatial_gen.qa import generate_qa, load_qa_config
    from refspatial_gen.sources.image import ImageSource
    from refspatial_gen.sources.image.annotations import annotation_mask, load_collection
    from refspatial_gen.sources.image.source import decode_rgb
    from refspatial_gen.yamlpos import load_yaml

    coll = load_collection(photos, "coco")
    ids = [i for i in coll.ids() if not any(a.iscrowd for a in coll.images[i].annotations)][: n + 1]
    work = Path(tempfile.mkdtemp(prefix="refspatial-overhead-"))
    answers: dict[str, list] = {}
    for iid in ids:
        rec = coll.images[iid]
        rgb = decode_rgb(rec.file)
        shutil.copy(rec.file, work / rec.file.name)
        answers[array_hash(rgb)] = [
            (a.bbox, a.category, annotation_mask(a, rec, rgb.shape[1], rgb.shape[0])[0]) for a in rec.annotations
        ]
    for name in ("det", "seg"):
        (work / "models" / name).mkdir(parents=True)
        (work / "models" / name / "config.json").write_text(
            '{"model_type": "%s"}' % ("grounding-dino" if name == "det" else "sam")
        )
    oracle = _Oracle(answers)
    saved = pipeline.load_model
    pipeline.load_model = lambda path, rt: oracle  # type: ignore[assignment]
    pipeline._perceiver.cache_clear()
    section = {
        "models": str(work / "models"),
        "cache": False,
        "filters": {"duplicate_distance": -1},
        "detector": {"model": "det", "vocabulary": "coco", "max_detections": 100},
        "segmenter": {"model": "seg", "min_box_fill": 0.0},
    }
    recipe = Path(__file__).resolve().parents[2] / "recipes" / "photos.yaml"
    data, lines = load_yaml(recipe)
    qa_cfg = load_qa_config(data["qa"], str(recipe), lines)
    cfg = {
        "perception": section,
        "_input": str(work),
        "images_dir": ".",
        "depth": {"estimator": "geometric", "max_size_ratio": 3.0, "size_fallback": True},
    }
    times, qa_pairs, dropped = [], 0, 0
    try:
        for i, iid in enumerate(ids):
            t0 = time.perf_counter()
            try:
                frames = ImageSource().load(f"image:{coll.images[iid].file.stem}", np.random.default_rng(0), cfg)
                graphs = [build_graph(f, {}) for f in frames]
                qa_pairs += len(generate_qa(frames, graphs, np.random.default_rng(0), qa_cfg)) if i else 0
            except DropUnit:
                dropped += 1 if i else 0
            if i:
                times.append(time.perf_counter() - t0)
    finally:
        pipeline.load_model = saved
        pipeline._perceiver.cache_clear()
        shutil.rmtree(work, ignore_errors=True)
    return {
        "images": len(times),
        "dropped": dropped,
        "qa_pairs": qa_pairs,
        "overhead_ms": round(1000 * float(np.mean(times)), 1) if times else None,
        "overhead_median_ms": round(1000 * float(np.median(times)), 1) if times else None,
    }


def per_image(photos: Path, n: int = 3, families: tuple[str, ...] = DEFAULT_FAMILIES, n_overhead: int = 20) -> dict:
    """Both measurements and their ratio."""
    models = model_times(photos, n, families)
    over = overhead(photos, n_overhead)
    ratio = None if not over["overhead_ms"] else round(over["overhead_ms"] / max(models["model_ms"], 1e-9), 4)
    return {"models": models, "overhead": over, "overhead_over_model_cpu": ratio}
