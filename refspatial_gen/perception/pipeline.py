"""The perception stages over a batch of images: filters, tagging, detection, masks, depth; cached.

`Perceiver.run(items)` takes images with their content hashes and returns, per image, a `Perceived` or
the `DropUnit` that drops it. Every model stage looks its outputs up in the disk cache first (key: image
content hash, model folder hash, the stage's settings and the runtime) and runs the model only for a
batch that misses; what the model returns is encoded exactly as the cache stores it and decoded back, so
a result read from the cache and one just computed are the same bytes. Batches are the caller's items
grouped by what the model needs to be equal (image size for models that keep the aspect ratio, the prompt
list for Grounding DINO), in item order, `batch_size` at a time: callers pass fixed blocks of images
(never "whatever arrived"), so a batch's composition, and with it every number, is the same whichever
worker computes it.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from refspatial_gen.core.errors import DropUnit
from refspatial_gen.perception import filters as flt
from refspatial_gen.perception.boxes import Detection, select
from refspatial_gen.perception.cache import key_of, make_cache
from refspatial_gen.perception.config import resolve_model
from refspatial_gen.perception.depth import DepthPrediction
from refspatial_gen.perception.runtime import folder_hash, load_model, make_runtime, read_config
from refspatial_gen.perception.vocab import load_vocabulary

STAGE_VERSION = "perception-v1"
SIZE_BATCHED = ("grounding-dino", "depth-anything", "zoedepth")  # input shape follows the image size


@dataclass
class Item:
    iid: str  # image id or frame id (messages only)
    content: str  # content hash: the cache key of the image
    rgb: np.ndarray


@dataclass
class Perceived:
    detections: list[Detection]
    masks: list[np.ndarray] | None  # per detection, when a segmenter runs
    mask_scores: list[float] | None
    depth: DepthPrediction | None
    scores: dict[str, float] = field(default_factory=dict)  # filter scores
    drops: dict[str, int] = field(default_factory=dict)  # detections removed, by reason
    names: list[str] = field(default_factory=list)  # the names the detector was asked (after tagging)


class NeedsCompute(Exception):
    """A cache-only pass found a stage not cached yet."""


@dataclass
class ModelRef:
    role: str
    name: str
    path: str
    digest: str
    family: str


class Perceiver:
    def __init__(self, cfg: dict[str, Any]) -> None:
        from refspatial_gen.perception.registry import family_of

        self.cfg = cfg
        self.rt = make_runtime(cfg)
        self.cache = make_cache(cfg)
        self.refs: dict[str, ModelRef] = {}
        for role in ("detector", "segmenter", "depth", "tagger"):
            if cfg.get(role):
                self._ref(role, cfg[role]["model"], family_of)
        if cfg["filters"].get("clip"):
            self._ref("filter", cfg["filters"]["clip"]["model"], family_of)
        for role in ("material", "vlm"):
            if cfg["captions"].get(role):
                self._ref(role, cfg["captions"][role]["model"], family_of)
        det = cfg["detector"]
        self.categories = load_vocabulary(det["vocabulary"], det.get("exclude"))
        per_cat = det.get("thresholds") or {}
        self.floor = min([det["threshold"], *[float(v) for v in per_cat.values()]])
        self.seconds: dict[str, float] = {}  # model time by stage (run log and bench only, never output)

    def _ref(self, role: str, name: str, family_of: Callable) -> None:
        path = str(resolve_model(name, self.cfg))
        self.refs[role] = ModelRef(role, name, path, folder_hash(path), family_of(read_config(path)) or "")

    def model(self, role: str):
        return load_model(self.refs[role].path, self.rt)

    def model_meta(self) -> dict[str, Any]:
        """What the output records about the models: folder names and content hashes (never paths)."""
        return {
            r: {"model": ref.name.rstrip("/").split("/")[-1], "family": ref.family, "sha256": ref.digest[:16]}
            for r, ref in sorted(self.refs.items())
        }

    def _key(self, role: str, content: str, *settings: Any) -> str:
        rt = self.rt
        return key_of(
            STAGE_VERSION, role, content, self.refs[role].digest, [rt.device, rt.threads, rt.batch_size], list(settings)
        )

    def cached(
        self, role: str, content: str, settings: list, compute: Callable[[], tuple[dict, dict]]
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """One cached model call outside the batched stages (captions of single objects)."""
        key = self._key(role, content, *settings)
        got = self.cache.get(role, key)
        if got is None:
            t0 = time.perf_counter()
            arrays, meta = compute()
            self.seconds[role] = self.seconds.get(role, 0.0) + time.perf_counter() - t0
            self.cache.put(role, key, arrays, meta)
            got = _roundtrip(arrays, meta)
            self.cache.remember(role, key, got)
        return got

    # ------------------------------------------------------------------ cached stage runner
    def _stage(
        self,
        role: str,
        items: list[Item],
        settings: Callable[[Item], list],
        group: Callable[[Item], Any],
        compute: Callable[[list[Item]], list[tuple[dict, dict]]],
        may_compute: bool,
    ) -> list[tuple[dict, dict]]:
        keys = [self._key(role, it.content, *settings(it)) for it in items]
        got: list[Any] = [self.cache.get(role, k) for k in keys]
        missing = [i for i, g in enumerate(got) if g is None]
        if missing and not may_compute:
            raise NeedsCompute(role)
        groups: dict[Any, list[int]] = {}
        for i, it in enumerate(items):
            groups.setdefault(group(it), []).append(i)
        for members in groups.values():
            if not any(got[i] is None for i in members):
                continue
            for s in range(0, len(members), self.rt.batch_size):
                chunk = members[s : s + self.rt.batch_size]
                t0 = time.perf_counter()
                outs = compute([items[i] for i in chunk])
                self.seconds[role] = self.seconds.get(role, 0.0) + time.perf_counter() - t0
                for i, (arrays, meta) in zip(chunk, outs):
                    if got[i] is None:
                        self.cache.put(role, keys[i], arrays, meta)
                        got[i] = _roundtrip(arrays, meta)
                        self.cache.remember(role, keys[i], got[i])
        return got

    # ------------------------------------------------------------------ the stages
    def run(
        self, items: list[Item], *, may_compute: bool = True, filters: bool = True, depth: bool = True
    ) -> list[Perceived | DropUnit]:
        """Every stage for every item; an item that fails a filter or has no detection gets its DropUnit."""
        out: list[Perceived | DropUnit | None] = [None] * len(items)
        scores: list[dict[str, float]] = [{} for _ in items]
        live = list(range(len(items)))
        if filters:
            for i in list(live):
                try:
                    scores[i] = flt.cheap_checks(items[i].rgb, self.cfg["filters"])
                except DropUnit as e:
                    out[i] = e
                    live.remove(i)
            if "filter" in self.refs:
                live = self._clip_filter(items, live, out, scores, may_compute)
        names = self._names(items, live, may_compute)
        dets = self._detect(items, live, names, out, may_compute)
        live = [i for i in live if out[i] is None]
        masks = self._segment(items, live, dets, may_compute) if "segmenter" in self.refs else {}
        depths = self._depth(items, live, may_compute) if depth and "depth" in self.refs else {}
        for i in live:
            kept, drops = dets[i]
            m = masks.get(i)
            out[i] = Perceived(
                kept,
                None if m is None else m[0],
                None if m is None else m[1],
                depths.get(i),
                scores[i],
                drops,
                names[i],
            )
        return out  # type: ignore[return-value]

    def _clip_filter(self, items, live, out, scores, may_compute) -> list[int]:
        c = self.cfg["filters"]["clip"]
        texts = [str(x) for x in c["positive"]] + [str(x) for x in c["negative"]]

        def compute(batch):
            p = self.model("filter").scores([it.rgb for it in batch], texts)
            return [({"p": p[k].astype(np.float32)}, {}) for k in range(len(batch))]

        got = self._stage("filter", [items[i] for i in live], lambda it: [texts], lambda it: 0, compute, may_compute)
        keep = []
        for i, (arr, _) in zip(live, got):
            p = arr["p"].astype(np.float64)
            margin = float(p[: len(c["positive"])].max() - p[len(c["positive"]) :].max())
            scores[i]["clip_margin"] = round(margin, 4)
            if margin <= c["min_margin"]:
                out[i] = DropUnit("image_rejected_by_clip", f"{items[i].iid}: margin {margin:.3f} <= {c['min_margin']}")
            else:
                keep.append(i)
        return keep

    def _names(self, items, live, may_compute) -> dict[int, list[str]]:
        """Per item, the names to detect: the vocabulary, or its top-k by the tagger (RefSpatial tags first)."""
        names = [c.name for c in self.categories]
        if "tagger" not in self.refs:
            return {i: names for i in live}
        t = self.cfg["tagger"]
        prompts = [t["prompt_template"].format(n) for n in names]

        def compute(batch):
            p = self.model("tagger").scores([it.rgb for it in batch], prompts)
            return [({"p": p[k].astype(np.float32)}, {}) for k in range(len(batch))]

        got = self._stage("tagger", [items[i] for i in live], lambda it: [prompts], lambda it: 0, compute, may_compute)
        out = {}
        for i, (arr, _) in zip(live, got):
            order = np.argsort(-arr["p"].astype(np.float64), kind="stable")[: t["top_k"]]
            out[i] = [names[k] for k in sorted(order)]  # vocabulary order: prompts do not depend on scores' ties
        return out

    def _detect(self, items, live, names, out, may_compute) -> dict[int, tuple[list[Detection], dict[str, int]]]:
        det = self.cfg["detector"]
        fam = self.refs["detector"].family
        by_size = fam in SIZE_BATCHED

        def prompts_of(i_names):
            return [det["prompt_template"].format(n) for n in i_names]

        idx = {id(items[i]): i for i in live}

        def compute(batch):
            nm = names[idx[id(batch[0])]]
            raw = self.model("detector").detect([it.rgb for it in batch], prompts_of(nm), nm, self.floor, det["chunk"])
            res = []
            for dets in raw:
                res.append(
                    (
                        {
                            "boxes": np.array([d.box for d in dets], np.float32).reshape(-1, 4),
                            "scores": np.array([d.score for d in dets], np.float32),
                            "labels": np.array([nm.index(d.label) for d in dets], np.int32),
                        },
                        {},
                    )
                )
            return res

        got = self._stage(
            "detector",
            [items[i] for i in live],
            lambda it: [prompts_of(names[idx[id(it)]]), round(self.floor, 6), det["chunk"]],
            lambda it: (tuple(names[idx[id(it)]]), it.rgb.shape[:2] if by_size else None),
            compute,
            may_compute,
        )
        res = {}
        for i, (arr, _) in zip(live, got):
            raw = [
                Detection(tuple(float(x) for x in b), float(s), names[i][int(lab)])
                for b, s, lab in zip(arr["boxes"], arr["scores"], arr["labels"])
            ]
            H, W = items[i].rgb.shape[:2]
            kept, drops = select(
                raw,
                W,
                H,
                threshold=det["threshold"],
                thresholds=det.get("thresholds"),
                nms_iou=det["nms_iou"],
                duplicate_iou=det["duplicate_iou"],
                max_detections=det["max_detections"],
                min_box_fraction=det["min_box_fraction"],
                max_box_fraction=det["max_box_fraction"],
            )
            res[i] = (kept, drops)
            if not kept:
                out[i] = DropUnit(
                    "no_detections",
                    f"{items[i].iid}: no box above its threshold ({len(raw)} candidates; dropped: {drops})",
                )
        return res

    def _segment(self, items, live, dets, may_compute) -> dict[int, tuple[list[np.ndarray], list[float]]]:
        seg = self.cfg["segmenter"]
        idx = {id(items[i]): i for i in live}

        def boxes_of(it):
            return [tuple(round(x, 2) for x in d.box) for d in dets[idx[id(it)]][0]]

        def compute(batch):
            res = self.model("segmenter").segment(
                [it.rgb for it in batch], [boxes_of(it) for it in batch], seg["multimask"]
            )
            return [
                (
                    {
                        "masks": np.packbits(np.stack(m).astype(bool), axis=-1),
                        "scores": np.array(s, np.float32),
                        "shape": np.array(np.stack(m).shape, np.int64),
                    },
                    {},
                )
                for m, s in res
            ]

        got = self._stage(
            "segmenter",
            [items[i] for i in live],
            lambda it: [boxes_of(it), seg["multimask"]],
            lambda it: 0,
            compute,
            may_compute,
        )
        out = {}
        for i, (arr, _) in zip(live, got):
            n, H, W = (int(x) for x in arr["shape"])
            m = np.unpackbits(arr["masks"], axis=-1, count=W).astype(bool).reshape(n, H, W)
            out[i] = ([m[k] for k in range(n)], [float(x) for x in arr["scores"]])
        return out

    def _depth(self, items, live, may_compute) -> dict[int, DepthPrediction]:
        by_size = self.refs["depth"].family in SIZE_BATCHED

        def compute(batch):
            preds = self.model("depth").predict([it.rgb for it in batch])
            return [
                (
                    {
                        "depth": p.depth.astype(np.float32),
                        "focal": np.array([np.nan if p.focal is None else p.focal], np.float64),
                    },
                    {"per_focal": bool(p.per_focal)},
                )
                for p in preds
            ]

        got = self._stage(
            "depth",
            [items[i] for i in live],
            lambda it: [],
            lambda it: it.rgb.shape[:2] if by_size else 0,
            compute,
            may_compute,
        )
        out = {}
        for i, (arr, meta) in zip(live, got):
            f = float(arr["focal"][0])
            out[i] = DepthPrediction(arr["depth"], bool(meta["per_focal"]), None if not np.isfinite(f) else f)
        return out


@lru_cache(maxsize=4)
def _perceiver(section_json: str) -> Perceiver:
    from refspatial_gen.perception.config import normalise

    return Perceiver(normalise(json.loads(section_json)))


def get_perceiver(section: dict[str, Any]) -> Perceiver:
    """The worker's Perceiver for a `perception:` section (models load once, on first use)."""
    return _perceiver(json.dumps(section, sort_keys=True))


def _roundtrip(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The value exactly as the cache would return it (dtypes kept, meta through JSON)."""
    from refspatial_gen.core.serialize import dumps

    return {k: np.array(v, copy=True) for k, v in arrays.items()}, json.loads(dumps(meta))
