"""Preview gallery: PNG overlays of a seeded sample of QA pairs from a shard folder, plus `index.html`.

Why: a data engineer must be able to *see* that answers land on the right object, that boxes and
free-space regions sit where the geometry says, and that questions and traces read well, before a
training job burns GPU hours on them. Each overlay draws the answer points, the target objects' 2D
boxes and projected 3D boxes, the frame's free-space regions (the answer's region highlighted), the
trace's Position key steps, and the question, answer, trace and checks as text under the image.

The choice of QA pairs is a seeded reservoir sample over the stream (shards in name order, samples
in stored order, QA pairs in order): same folder and seed -> same selection and same PNG bytes, with
at most `n` samples held in memory however large the folder is.
"""

from __future__ import annotations

import html
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, TypeVar

import numpy as np

from refspatial_gen.core.mask import denormalise_point
from refspatial_gen.core.model import Frame, FreeSpaceRegion, QAPair, Sample, SceneGraph
from refspatial_gen.core.serialize import encode_png
from refspatial_gen.run import draw

SHARD_SUFFIX = ".mcap"
T = TypeVar("T")


# ---------------------------------------------------------------------------------------------- answers
def answer_points(struct: dict[str, Any]) -> list[tuple[float, float]]:
    """Normalised (x, y) answer points of an `answer_struct` (`points` list and/or a single `point`)."""
    pts = list(struct.get("points") or [])
    if struct.get("point") is not None:
        pts.append(struct["point"])
    out = []
    for p in pts:
        if isinstance(p, (list, tuple)) and len(p) == 2:
            out.append((float(p[0]), float(p[1])))
    return out


def _answer_frame(sample: Sample, qa: QAPair) -> Frame:
    """The frame the answer's points refer to: `answer_struct.frame_id`, else the question's first frame."""
    want = qa.answer_struct.get("frame_id") or (qa.frame_ids[0] if qa.frame_ids else None)
    for f in sample.frames:
        if want is None or f.frame_id == want:
            return f
    raise KeyError(f"sample {sample.sample_id}: QA {qa.qa_id} refers to frame {want!r}, not in the sample")


def question_frames(sample: Sample, qa: QAPair) -> list[Frame]:
    """The frames a question is about, in the order the question names them ("the first image" is
    `qa.frame_ids[0]`), which need not be the order the sample stores them in."""
    by_id = {f.frame_id: f for f in sample.frames}
    return [by_id[fid] for fid in qa.frame_ids if fid in by_id]


def _graph_for(sample: Sample, frame: Frame) -> SceneGraph | None:
    for g in sample.graphs:
        if g.frame_id == frame.frame_id:
            return g
    return None


def _region_of_answer(struct: dict[str, Any], graph: SceneGraph | None) -> FreeSpaceRegion | None:
    """The free-space region a placement answer refers to: stored in the struct, or the graph's region
    whose representative point is the answer point."""
    reg = struct.get("region")
    if isinstance(reg, dict) and "polygon_xy" in reg and "z" in reg:
        return FreeSpaceRegion.from_json({"surface_id": "", "kind": "", "anchors": [], "area": 0.0,
                                          "point_world": [0, 0, 0], "point": [0, 0], **reg})
    if graph is None:
        return None
    pts = answer_points(struct)
    for r in graph.free_space:
        if any(abs(r.point[0] - x) < 5e-4 and abs(r.point[1] - y) < 5e-4 for x, y in pts):
            return r
    return None


def _inside_polygon(uv: np.ndarray, x: float, y: float) -> bool:
    import cv2

    return cv2.pointPolygonTest(np.asarray(uv, np.float32).reshape(-1, 1, 2), (float(x), float(y)), False) >= 0


def _is_placement(qa: QAPair) -> bool:
    return qa.answer_struct.get("kind") == "region" or qa.family == "placement"


def _marks(struct: dict[str, Any]) -> list[dict[str, Any]]:
    """Visual-choice marks (`answer_struct.marks`) and option records carrying a point or a box."""
    out = []
    for i, m in enumerate(list(struct.get("marks") or []) + [o for o in struct.get("options") or [] if isinstance(o, dict)]):
        if isinstance(m, dict):
            out.append({**m, "label": str(m.get("label") or m.get("letter") or chr(ord("A") + i))})
    return out


def _mask_of(frame: Frame, oid: Any) -> np.ndarray | None:
    try:
        obj = frame.object(int(oid))
    except (KeyError, TypeError, ValueError):
        return None
    return None if obj.mask is None else obj.mask.decode()


def point_checks(sample: Sample, qa: QAPair) -> list[tuple[str, bool]]:
    """Human-readable checks of the answer against the stored scene, re-done here independently.

    - an object point (`kind: points`) must denormalise to a pixel inside a target's visible mask
      (`answer_struct.object_ids`, else `QAPair.targets`): the rule the generators follow;
    - a placement point (`kind: region`) must fall inside its free-space region's projection;
    - a visual-choice mark must sit on its object's mask, and the correct letter must name a target.
    Returns (text, passed) per check.
    """
    frame = _answer_frame(sample, qa)
    W, H = frame.camera.width, frame.camera.height
    struct = qa.answer_struct
    out: list[tuple[str, bool]] = []
    if _is_placement(qa):
        region = _region_of_answer(struct, _graph_for(sample, frame))
        region_uv = None if region is None else draw.project_polygon(frame.camera, region.polygon_xy, region.z)
        for k, (x, y) in enumerate(answer_points(struct), 1):
            px, py = denormalise_point(x, y, W, H)
            head = f"point {k} ({x:.3f}, {y:.3f}) -> pixel ({px}, {py})"
            if region_uv is None:
                out.append((f"{head}; free-space region: NOT FOUND", False))
            else:
                inside = _inside_polygon(region_uv, px + 0.5, py + 0.5)
                out.append((f"{head}; in free-space region: " + ("yes" if inside else "NO"), inside))
        return out
    ids = struct.get("object_ids") or qa.targets
    masks = [(int(oid), m) for oid in ids if (m := _mask_of(frame, oid)) is not None]
    for k, (x, y) in enumerate(answer_points(struct), 1):
        px, py = denormalise_point(x, y, W, H)
        head = f"point {k} ({x:.3f}, {y:.3f}) -> pixel ({px}, {py})"
        if not masks:
            out.append((f"{head}; no target mask to check", True))
            continue
        hit = [oid for oid, m in masks if m[py, px]]
        out.append((f"{head}; in target mask #{hit[0]}: yes" if hit else f"{head}; in a target mask: NO", bool(hit)))
    letter = struct.get("letter")
    for m in _marks(struct):
        view = int(m.get("view", 0) or 0)
        f = sample.frames[view] if 0 <= view < len(sample.frames) else None
        oid = m.get("object_id")
        if f is None or oid is None or not isinstance(m.get("point"), (list, tuple)):
            continue
        mask = _mask_of(f, oid)
        px, py = denormalise_point(float(m["point"][0]), float(m["point"][1]), f.camera.width, f.camera.height)
        ok = mask is not None and bool(mask[py, px])
        text = f"mark ({m['label']}) #{oid}: point in its mask: {'yes' if ok else 'NO'}"
        if m["label"] == letter and qa.targets:
            is_target = int(oid) in [int(t) for t in qa.targets]
            text += f"; correct mark is the target: {'yes' if is_target else 'NO'}"
            ok = ok and is_target
        out.append((text, ok))
    return out


# ---------------------------------------------------------------------------------------------- render
def _draw_frame(sample: Sample, qa: QAPair, frame: Frame, answer_frame: bool) -> tuple[np.ndarray, set[str]]:
    """One frame with its overlays; returns the image and the legend keys used."""
    ov = draw.Overlay.from_rgb(frame.rgb)
    cam = frame.camera
    W, H = cam.width, cam.height
    used: set[str] = set()
    struct = qa.answer_struct
    placement = _is_placement(qa)
    graph = _graph_for(sample, frame)
    if placement:  # free space matters (and is readable) only where the question is about it
        region = _region_of_answer(struct, graph) if answer_frame else None
        seen: dict[float, np.ndarray] = {}

        def visible(z: float) -> np.ndarray:
            if z not in seen:
                seen[z] = draw.plane_visibility(cam, frame.depth, z)
            return seen[z]

        for r in (graph.free_space if graph is not None else []):
            uv = draw.project_polygon(cam, r.polygon_xy, r.z)
            if uv is not None and (region is None or r is not region):
                ov.polygon(uv, draw.FREE_SPACE, fill_alpha=0, width=1, visible=visible(float(r.z)))  # outlines: regions overlap
                used.add("free")
        if region is not None:
            uv = draw.project_polygon(cam, region.polygon_xy, region.z)
            if uv is not None:
                ov.polygon(uv, draw.ANSWER_REGION, fill_alpha=90, width=3, visible=visible(float(region.z)))
                used.add("region")
    if answer_frame:
        for oid in qa.targets:
            try:
                obj = frame.object(int(oid))
            except KeyError:
                continue
            role = "anchor" if placement else "target"  # a placement answer is free space near its anchors
            ov.segments(draw.project_box_edges(cam, obj.box), draw.TARGET_3D, width=2)
            used.add(f"{role}3d")
            if obj.bbox2d is not None:
                ov.rect(obj.bbox2d, draw.TARGET_2D, width=2, label=f"{'anchor ' if placement else ''}#{obj.id} {obj.category}")
                used.add(f"{role}2d")
    view = next((i for i, f in enumerate(sample.frames) if f is frame), -1)
    for m in _marks(struct):
        if int(m.get("view", 0) or 0) != view:
            continue
        correct = m["label"] == struct.get("letter")
        color, width = (draw.ANSWER, 4) if correct else (draw.OPTION, 2)
        box = m.get("box") or m.get("bbox2d")
        if isinstance(box, (list, tuple)) and len(box) == 4:
            ov.rect(box, color, width=width, label=f"({m['label']})", label_below=True)
        elif isinstance(m.get("point"), (list, tuple)) and len(m["point"]) == 2:
            ov.point(float(m["point"][0]) * W, float(m["point"][1]) * H, color, f"({m['label']})", radius=6)
        else:
            continue
        used.add("answer_mark" if correct else "option")
    if answer_frame:
        pts = answer_points(struct)
        for k, ks in enumerate(qa.key_steps, 1):
            if ks.type != "Position" or len(ks.value) != 2:
                continue
            if any(abs(ks.value[0] - x) * W < 1.5 and abs(ks.value[1] - y) * H < 1.5 for x, y in pts):
                continue  # the answer marker is drawn there
            ov.point(ks.value[0] * W, ks.value[1] * H, draw.KEY_STEP, f"s{k}", radius=9, hollow=True)
            used.add("step")
        for k, (x, y) in enumerate(pts, 1):
            ov.point(x * W, y * H, draw.ANSWER, f"A{k}" if len(pts) > 1 else "A")
            used.add("answer")
    return ov.rgb(), used


_LEGEND = [("answer", draw.ANSWER, "answer point"), ("answer_mark", draw.ANSWER, "correct mark"),
           ("option", draw.OPTION, "other marks"), ("region", draw.ANSWER_REGION, "answer region"),
           ("free", draw.FREE_SPACE, "free space"), ("target2d", draw.TARGET_2D, "target 2D box"),
           ("target3d", draw.TARGET_3D, "target 3D box"), ("anchor2d", draw.TARGET_2D, "anchor 2D box"),
           ("anchor3d", draw.TARGET_3D, "anchor 3D box"), ("step", draw.KEY_STEP, "trace position")]


def _struct_text(struct: dict[str, Any]) -> str:
    s = json.dumps(struct, sort_keys=True, ensure_ascii=False)
    return s if len(s) <= 400 else s[:397] + "..."


def render_preview(sample: Sample, qa_index: int) -> np.ndarray:
    """The overlay image (uint8 RGB) for `sample.qa[qa_index]`: frames side by side, text underneath."""
    qa = sample.qa[qa_index]
    ans_frame = _answer_frame(sample, qa)
    frames = question_frames(sample, qa) or [ans_frame]
    tiles, used = [], set()
    for k, f in enumerate(frames, 1):
        img, u = _draw_frame(sample, qa, f, f is ans_frame)
        tiles.append(draw.caption_above(img, f"image {k}: {f.frame_id}") if len(frames) > 1 else img)
        used |= u
    top = draw.hstack(tiles)
    width = max(top.shape[1], 640)
    rels = ", ".join(qa.relations) or "-"
    blocks: list[tuple[str, str, draw.RGB]] = [
        (f"{qa.family} · {qa.template} · {qa.steps} step{'s' if qa.steps != 1 else ''} · relations: {rels}",
         "bold", (150, 200, 255)),
        (f"Q: {qa.question}", "regular", (240, 240, 240)),
        (f"A: {qa.answer}", "bold", (255, 140, 140)),
        (f"answer_struct: {_struct_text(qa.answer_struct)}", "mono", (180, 180, 180)),
    ]
    if qa.trace:
        blocks.append((f"trace:\n{qa.trace}", "mono", (255, 200, 120)))
    if qa.key_steps:
        ks = "\n".join(f"s{k} [{s.type}] {s.phrase}: {', '.join(f'{v:.3f}' for v in s.value)}"
                       for k, s in enumerate(qa.key_steps, 1))
        blocks.append((f"key steps:\n{ks}", "mono", (255, 200, 120)))
    checks = point_checks(sample, qa)
    if checks:
        bad = not all(ok for _, ok in checks)
        blocks.append(("preview check:\n" + "\n".join(t for t, _ in checks), "mono",
                       (255, 90, 90) if bad else (140, 230, 140)))
    if qa.checks:
        blocks.append(("generator checks passed: " + ", ".join(qa.checks), "regular", (170, 170, 170)))
    W, H = qa.image_size
    blocks.append((f"sample {sample.sample_id} · qa {qa.qa_id} · frames {', '.join(f.frame_id for f in frames)}"
                   f" · image {W}x{H}", "regular", (140, 140, 140)))
    leg = draw.legend([(c, label) for key, c, label in _LEGEND if key in used], width) if used else None
    panel = draw.text_panel(blocks, width)
    out = draw.vstack(top, leg) if leg is not None else top
    return draw.vstack(out, panel)


# ---------------------------------------------------------------------------------------------- sampling
@dataclass(frozen=True)
class Pick:
    """One chosen QA pair: its position in the stream and where it came from."""

    order: int  # index of the QA pair in the stream (shards by name, samples in order, QA in order)
    source: str  # shard file name (or "" for in-memory samples)
    sample_id: str
    qa_index: int
    qa_id: str


def reservoir(items: Iterable[T], n: int, seed: int) -> list[tuple[int, T]]:
    """Algorithm R with a seeded Generator: `n` items uniformly from a stream of unknown length.

    Returns (stream position, item) sorted by position; holds at most `n` items at any time.
    """
    if n <= 0:
        return []
    rng = np.random.default_rng(seed)
    chosen: list[tuple[int, T]] = []
    for t, item in enumerate(items):
        if len(chosen) < n:
            chosen.append((t, item))
        else:
            j = int(rng.integers(0, t + 1))
            if j < n:
                chosen[j] = (t, item)
    return sorted(chosen, key=lambda ti: ti[0])


def reservoir_pick(stream: Iterable[tuple[str, Sample]], n: int, seed: int) -> list[tuple[Pick, Sample]]:
    """`n` QA pairs from `(source name, Sample)` pairs, every QA pair equally likely; in stream order.

    Only samples with a chosen QA pair are kept, so memory does not grow with the stream.
    """
    items = ((src, s, qi) for src, s in stream for qi in range(len(s.qa)))
    return [(Pick(t, src, s.sample_id, qi, s.qa[qi].qa_id), s) for t, (src, s, qi) in reservoir(items, n, seed)]


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name)[:80]


def write_gallery(stream: Iterable[tuple[str, Sample]], out: Path, n: int = 24, seed: int = 0,
                  title: str = "refspatial-gen preview") -> Path:
    """Render a seeded sample of `n` QA pairs from `(source_name, Sample)` pairs into `out`; returns index.html."""
    return render_gallery(reservoir_pick(stream, n, seed), out, n, seed, title)


def render_gallery(picks: list[tuple[Pick, Sample]], out: Path, n: int, seed: int, title: str) -> Path:
    """One PNG per picked QA pair, `preview.json` listing them, and `index.html` linking them."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("qa_*.png"):  # a re-run must not leave images of another selection
        old.unlink()
    cards, listing = [], []
    for k, (pick, sample) in enumerate(picks):
        qa = sample.qa[pick.qa_index]
        if qa.qa_id != pick.qa_id:
            raise ValueError(f"{pick.source}: sample {pick.sample_id} QA {pick.qa_index} is {qa.qa_id}, expected {pick.qa_id}")
        name = f"qa_{k:03d}_{_safe(pick.qa_id)}.png"
        (out / name).write_bytes(encode_png(render_preview(sample, pick.qa_index)))
        checks = point_checks(sample, qa)
        listing.append({"file": name, "order": pick.order, "source": pick.source, "sample_id": pick.sample_id,
                        "qa_index": pick.qa_index, "qa_id": pick.qa_id, "family": qa.family, "steps": qa.steps,
                        "checks": [{"text": t, "ok": ok} for t, ok in checks]})
        cards.append(_card(name, pick, qa, listing[-1]["checks"]))
    (out / "preview.json").write_text(json.dumps({"seed": seed, "n": n, "picked": listing}, indent=1,
                                                 sort_keys=True, ensure_ascii=False) + "\n", encoding="utf-8")
    index = out / "index.html"
    index.write_text(_page(title, seed, cards), encoding="utf-8")
    return index


def _card(name: str, pick: Pick, qa: QAPair, checks: list[dict]) -> str:
    e = html.escape
    bad = not all(c["ok"] for c in checks)
    flag = '<span class="bad">point check failed</span>' if bad else ""
    src = f" · {e(pick.source)}" if pick.source else ""
    return (f'<figure class="card"><a href="{e(name)}"><img src="{e(name)}" loading="lazy" alt="{e(qa.qa_id)}"></a>'
            f'<figcaption><div class="meta">{e(qa.family)} · {qa.steps} step{"s" if qa.steps != 1 else ""}'
            f' · {e(", ".join(qa.relations) or "-")} {flag}</div>'
            f'<div class="q">{e(qa.question)}</div><div class="a">{e(qa.answer)}</div>'
            f'<div class="id">{e(pick.sample_id)} · {e(pick.qa_id)}{src}</div></figcaption></figure>')


_CSS = """
body{font-family:system-ui,-apple-system,"DejaVu Sans",sans-serif;margin:0;background:#f4f5f7;color:#1d1f23}
header{background:#1d1f23;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;color:#bbb;font-size:13px}
main{display:grid;grid-template-columns:repeat(auto-fill,minmax(440px,1fr));gap:16px;padding:16px 24px}
.card{margin:0;background:#fff;border-radius:6px;box-shadow:0 1px 3px rgba(0,0,0,.15);overflow:hidden}
.card img{display:block;width:100%;height:auto}.card figcaption{padding:8px 12px 12px;font-size:13px}
.meta{color:#555;font-size:12px}.q{margin-top:6px}.a{margin-top:4px;font-weight:600;color:#b3261e}
.id{margin-top:6px;color:#888;font-size:11px;word-break:break-all}.bad{color:#fff;background:#b3261e;padding:0 4px}
"""


def _page(title: str, seed: int, cards: list[str]) -> str:
    e = html.escape
    body = "\n".join(cards) if cards else "<p>No QA pairs found.</p>"
    return (f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>'
            f"<style>{_CSS}</style></head><body>\n<header><h1>{e(title)}</h1>"
            f"<p>{len(cards)} QA pairs, seeded sample (seed {seed}). Click an image for full size.</p></header>\n"
            f"<main>\n{body}\n</main></body></html>\n")


# ---------------------------------------------------------------------------------------------- shards
def shard_paths(folder: Path) -> list[Path]:
    """Complete shard files under `folder`, in a stable order (relative path)."""
    folder = Path(folder)
    if folder.is_file():
        return [folder]
    return sorted((p for p in folder.rglob(f"*{SHARD_SUFFIX}") if p.is_file()),
                  key=lambda p: p.relative_to(folder).as_posix())


def _shard_names(folder: Path) -> list[tuple[str, Path]]:
    folder = Path(folder)
    return [(p.name if folder.is_file() else p.relative_to(folder).as_posix(), p) for p in shard_paths(folder)]


def iter_shard_samples(folder: Path) -> Iterator[tuple[str, Sample]]:
    """(shard name, Sample) over every shard under `folder`, fully decoded, via the shard reader."""
    from refspatial_gen.shards.reader import read_samples

    for name, p in _shard_names(folder):
        for s in read_samples(p):
            yield name, s


def pick_from_shards(folder: Path, n: int, seed: int) -> list[tuple[Pick, Sample]]:
    """The same picks as `reservoir_pick(iter_shard_samples(folder), n, seed)`, but cheap on big folders:
    the sampling pass reads only metadata (no pixels decoded), then only the picked samples are decoded."""
    from refspatial_gen.shards.reader import ShardError, iter_raw, read_sample_meta

    shards = _shard_names(folder)
    items = ((name, p, m["seq"], m["sample_id"], qi, q["qa_id"])
             for name, p in shards for m in read_sample_meta(p) for qi, q in enumerate(m["qa"]))
    chosen = reservoir(items, n, seed)
    wanted: dict[Path, set[int]] = {}
    for _, (_, p, seq, *_rest) in chosen:
        wanted.setdefault(p, set()).add(seq)
    loaded: dict[tuple[Path, int], Sample] = {}
    for _, p in shards:
        if p not in wanted:
            continue
        for raw in iter_raw(p):
            if raw.seq in wanted[p]:
                try:
                    loaded[(p, raw.seq)] = raw.decode()
                except (ValueError, KeyError, TypeError) as e:
                    raise ShardError(p, f"sample with sequence {raw.seq} does not decode: {e}") from None
    return [(Pick(t, name, sid, qi, qa_id), loaded[(p, seq)]) for t, (name, p, seq, sid, qi, qa_id) in chosen]


def preview_dir(folder: Path, out: Path, n: int = 24, seed: int = 0) -> Path:
    """`refspatial-gen preview`: gallery of `n` seeded QA pairs from the shards under `folder`."""
    if not shard_paths(folder):
        raise FileNotFoundError(f"no {SHARD_SUFFIX} shards under {folder}")
    return render_gallery(pick_from_shards(folder, n, seed), out, n, seed,
                          title=f"refspatial-gen preview: {Path(folder).resolve().name}")
