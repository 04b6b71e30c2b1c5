"""Render an audit folder: one PNG per picked QA pair (the preview overlay: image with the answer drawn,
question, answer, trace, key steps), the objects it names, and a keyboard-driven review page.

Layout of `out/`: `sample.jsonl` (the items, in page order, with what the reviewer needs), `items/*.png`,
`index.html`, and `verdicts.jsonl` (appended by the page through `audit serve`, or by `audit mark`).
"""

from __future__ import annotations

import html
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from refspatial_gen.audit.sample import Item, candidates, parse_dataset_args, parts, stratified
from refspatial_gen.audit.verdicts import SAMPLE_FILE, VERDICT_FILE
from refspatial_gen.core.model import QAPair, Sample


def named_object_ids(qa: QAPair) -> list[int]:
    """Object ids a question's program, answer and targets refer to, in first-mention order."""
    seen: list[int] = []

    def walk(x: Any) -> None:
        if isinstance(x, dict):
            for k, v in x.items():
                if k in ("object", "object_id") and isinstance(v, int) and not isinstance(v, bool):
                    seen.append(v)
                elif k in ("object_ids", "option_ids", "options", "out") and isinstance(v, list):
                    seen.extend(i for i in v if isinstance(i, int) and not isinstance(i, bool))
                    walk(v)
                else:
                    walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)

    walk(qa.program)
    walk(qa.answer_struct)
    seen.extend(qa.targets)
    return list(dict.fromkeys(seen))


def object_rows(sample: Sample, qa: QAPair) -> list[dict[str, Any]]:
    """What a reviewer needs about each named object: category, phrases, colour word, visible pixels and
    fraction, metric size; from the first question frame that holds it."""
    frames = [f for fid in qa.frame_ids for f in sample.frames if f.frame_id == fid] or sample.frames
    rows = []
    for oid in named_object_ids(qa):
        for f in frames:
            try:
                o = f.object(oid)
            except KeyError:
                continue
            g = next((g for g in sample.graphs if g.frame_id == f.frame_id), None)
            node = next((n for n in g.nodes if n.object_id == oid), None) if g is not None else None
            rows.append(
                {
                    "id": oid,
                    "frame": f.frame_id,
                    "category": o.category,
                    "phrases": list(node.phrases[:3]) if node is not None else [],
                    "color": (node.attributes.get("color") if node is not None else None) or o.attributes.get("color"),
                    "visible_px": int(o.mask.area) if o.mask is not None else None,
                    "visible_fraction": round(float(o.visible_fraction), 3),
                    "size_m": [round(float(v), 3) for v in o.box.size],
                }
            )
            break
    return rows


def object_crop(sample: Sample, frame_id: str, oid: int, min_side: int = 160) -> np.ndarray | None:
    """The object's 2D box (with a margin) cut from its frame and enlarged so a small object can be judged:
    a reviewer must see what the phrase refers to, not a speck under an overlay label."""
    import cv2

    f = next((f for f in sample.frames if f.frame_id == frame_id), None)
    if f is None:
        return None
    try:
        o = f.object(oid)
    except KeyError:
        return None
    if o.bbox2d is None:
        return None
    x0, y0, x1, y1 = (float(v) for v in o.bbox2d)
    m = max(8.0, 0.25 * max(x1 - x0, y1 - y0))
    H, W = f.rgb.shape[:2]
    a, b = int(max(0, x0 - m)), int(max(0, y0 - m))
    c, d = int(min(W, x1 + m + 1)), int(min(H, y1 + m + 1))
    if c <= a or d <= b:
        return None
    crop = f.rgb[b:d, a:c].copy()
    scale = max(1.0, min_side / max(1, min(crop.shape[:2])))
    size = (int(crop.shape[1] * scale), int(crop.shape[0] * scale))
    if scale > 1.0:
        crop = cv2.resize(crop, size, interpolation=cv2.INTER_NEAREST)
    if o.mask is not None:  # outline the visible mask (after enlarging, so the outline hides no pixel of it)
        mk = cv2.resize(o.mask.decode()[b:d, a:c].astype(np.uint8), size, interpolation=cv2.INTER_NEAREST)
        contours, _ = cv2.findContours(mk, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        grown = [c + np.sign(c - c.mean(axis=0)).astype(c.dtype) for c in contours]
        cv2.drawContours(crop, grown, -1, (255, 0, 255), 1)
    return crop


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name)[:100]


def _decode_picked(folder_of: dict[tuple[str, int], Path], items: list[Item]) -> dict[tuple, Sample]:
    """Decode only the samples holding picked items: one pass per shard that holds any."""
    from refspatial_gen.shards.reader import iter_raw

    wanted: dict[tuple[str, int, str], set[int]] = {}
    for it in items:
        wanted.setdefault((it.label, it.part, it.shard), set()).add(it.seq)
    out: dict[tuple, Sample] = {}
    for (label, part, shard), seqs in sorted(wanted.items()):
        for raw in iter_raw(folder_of[(label, part)] / shard):
            if raw.seq in seqs:
                out[(label, part, shard, raw.seq)] = raw.decode()
    return out


def build_audit(datasets: list[str], out: Path, n: int = 150, seed: int = 0, min_per_label: int = 30) -> Path:
    """Pick and render an audit of `n` QA pairs over `datasets` (`LABEL=DIR` or `DIR`); returns index.html.

    Verdicts already in `out/verdicts.jsonl` are kept (the same command gives the same items)."""
    from refspatial_gen.core.serialize import encode_png
    from refspatial_gen.run.preview import point_checks, render_preview

    pairs = parse_dataset_args(datasets)
    folder_of = {(lab, k): d for lab, k, d in parts(pairs)}
    by_label: dict[str, list[Item]] = {}
    for lab, k, d in parts(pairs):
        by_label.setdefault(lab, []).extend(candidates(lab, k, d))
    items = stratified(by_label, n, seed, min_per_label)
    samples = _decode_picked(folder_of, items)
    out = Path(out)
    (out / "items").mkdir(parents=True, exist_ok=True)
    for old in (out / "items").glob("*.png"):
        old.unlink()
    rows = []
    for k, it in enumerate(items):
        sample = samples[(it.label, it.part, it.shard, it.seq)]
        qa = sample.qa[it.qa_index]
        if qa.qa_id != it.qa_id:
            raise ValueError(
                f"{it.label}/{it.shard}: sample {it.sample_id} QA {it.qa_index} is {qa.qa_id}, not {it.qa_id}"
            )
        png = f"items/{k:03d}_{_safe(it.item_id)}.png"
        (out / png).write_bytes(encode_png(render_preview(sample, it.qa_index)))
        objects = object_rows(sample, qa)
        for o in objects:
            crop = object_crop(sample, o["frame"], o["id"])
            if crop is not None:
                o["crop"] = f"items/{k:03d}_{_safe(it.item_id)}_obj{o['id']}.png"
                (out / o["crop"]).write_bytes(encode_png(crop))
        rows.append(
            {
                **it.to_json(),
                "png": png,
                "template": qa.template,
                "question": qa.question,
                "answer": qa.answer,
                "trace": qa.trace,
                "relations": list(qa.relations),
                "objects": objects,
                "checks": [{"text": t, "ok": ok} for t, ok in point_checks(sample, qa)],
            }
        )
    (out / SAMPLE_FILE).write_text(
        "".join(json.dumps(r, sort_keys=True, ensure_ascii=False) + "\n" for r in rows), encoding="utf-8"
    )
    (out / "audit.json").write_text(
        json.dumps(
            {
                "datasets": [[lab, str(d)] for lab, d in pairs],
                "n": n,
                "seed": seed,
                "min_per_label": min_per_label,
                "items": len(rows),
            },
            indent=1,
            sort_keys=True,
        )
        + "\n",
        encoding="utf-8",
    )
    (out / VERDICT_FILE).touch()
    index = out / "index.html"
    index.write_text(render_page(rows), encoding="utf-8")
    return index


_CSS = """
body{font-family:system-ui,"DejaVu Sans",sans-serif;margin:0;background:#f4f5f7;color:#1d1f23}
header{background:#1d1f23;color:#fff;padding:10px 20px;position:sticky;top:0;z-index:2}
header h1{margin:0;font-size:18px}header p{margin:2px 0 0;color:#bbb;font-size:13px}
.item{display:none;padding:12px 20px}.item.cur{display:block}
.item img{max-width:100%;border:1px solid #ccc}.item img.crop{max-height:200px;max-width:260px}
table{border-collapse:collapse;font-size:13px;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;text-align:left}
.v{font-weight:700;padding:2px 8px;border-radius:4px}.right{background:#c8efc8}.wrong{background:#f6c4c0}
.ambiguous{background:#f8e6a8}.none{background:#ddd}
textarea{width:60%;height:3em}button{margin-right:6px}
"""

_JS = r"""
const items = JSON.parse(document.getElementById('items').textContent);
const served = location.protocol.startsWith('http');
let cur = 0, verdicts = {};
function key(){return 'refspatial-audit:' + document.title;}
function show(){document.querySelectorAll('.item').forEach((e,i)=>e.classList.toggle('cur', i===cur));
  const v = verdicts[items[cur].item_id]; const el = document.getElementById('v'+cur);
  el.textContent = v ? v.verdict : 'unjudged'; el.className = 'v ' + (v ? v.verdict : 'none');
  document.getElementById('note'+cur).value = v ? v.note : '';
  const done = Object.keys(verdicts).length;
  document.getElementById('progress').textContent = `item ${cur+1} of ${items.length} · ${done} judged` +
    (served ? ' · saved to verdicts.jsonl' : ' · opened as a file: verdicts kept in this browser, use Download');}
function save(verdict){const id = items[cur].item_id; const note = document.getElementById('note'+cur).value;
  verdicts[id] = {item_id:id, verdict:verdict, note:note};
  if (served) {fetch('verdict', {method:'POST', headers:{'Content-Type':'application/json'},
     body: JSON.stringify(verdicts[id])}).then(r=>{if(!r.ok) alert('not saved: ' + r.status);});}
  else {localStorage.setItem(key(), JSON.stringify(verdicts));}
  show(); if (cur < items.length-1) {cur++; show();}}
function download(){const lines = Object.values(verdicts).map(v=>JSON.stringify(v)).join('\n') + '\n';
  const a = document.createElement('a'); a.href = URL.createObjectURL(new Blob([lines], {type:'application/json'}));
  a.download = 'verdicts.jsonl'; a.click();}
document.addEventListener('keydown', e => {
  if (e.target.tagName === 'TEXTAREA') {if (e.key === 'Escape') e.target.blur(); return;}
  if (e.key === 'r') save('right'); else if (e.key === 'w') save('wrong'); else if (e.key === 'a') save('ambiguous');
  else if (e.key === 'n') {e.preventDefault(); document.getElementById('note'+cur).focus();}
  else if (e.key === 'ArrowRight' || e.key === 'j') {cur = Math.min(items.length-1, cur+1); show();}
  else if (e.key === 'ArrowLeft' || e.key === 'k') {cur = Math.max(0, cur-1); show();}});
function load(){ if (served) { fetch('verdicts.jsonl').then(r=>r.text()).then(t=>{
    t.split('\n').filter(l=>l.trim()).forEach(l=>{const v = JSON.parse(l); verdicts[v.item_id] = v;}); show();}); }
  else { verdicts = JSON.parse(localStorage.getItem(key()) || '{}'); show(); } }
load();
"""


def _crop_img(o: dict[str, Any]) -> str:
    return f'<img class="crop" src="{html.escape(o["crop"])}" alt="object {o["id"]}">' if o.get("crop") else ""


def _item_html(k: int, r: dict[str, Any]) -> str:
    e = html.escape
    objs = "".join(
        f"<tr><td>#{o['id']}<br>{_crop_img(o)}</td><td>{e(o['category'])}</td><td>{e('; '.join(o['phrases']))}</td>"
        f"<td>{e(str(o['color'] or '-'))}</td><td>{o['visible_px']}</td><td>{o['visible_fraction']}</td>"
        f"<td>{' × '.join(f'{v:.2f}' for v in o['size_m'])}</td></tr>"
        for o in r["objects"]
    )
    table = (
        (
            "<table><tr><th>id</th><th>category</th><th>phrases</th><th>colour</th><th>visible px</th>"
            f"<th>visible fraction</th><th>size (m)</th></tr>{objs}</table>"
        )
        if objs
        else "<p>No object named.</p>"
    )
    return (
        f'<section class="item" id="item{k}"><p><b>{e(r["item_id"])}</b> · {e(r["label"])} · {e(r["family"])} · '
        f'{r["steps"]} step(s) · {e(r["template"])} · <span class="v none" id="v{k}">unjudged</span></p>'
        f"<p>Q: {e(r['question'])}<br><b>A: {e(r['answer'])}</b></p>"
        f'<img src="{e(r["png"])}" alt="{e(r["item_id"])}">{table}'
        f"<p><button onclick=\"save('right')\">right (r)</button><button onclick=\"save('wrong')\">wrong (w)</button>"
        f"<button onclick=\"save('ambiguous')\">ambiguous (a)</button></p>"
        f'<textarea id="note{k}" placeholder="note (n to type, Esc to leave): what is wrong or unclear"></textarea>'
        "</section>"
    )


def render_page(rows: list[dict[str, Any]]) -> str:
    items_json = json.dumps([{"item_id": r["item_id"]} for r in rows]).replace("</", "<\\/")
    body = "\n".join(_item_html(k, r) for k, r in enumerate(rows)) or "<p>No QA pairs found.</p>"
    return (
        '<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>refspatial-gen audit</title>'
        f"<style>{_CSS}</style></head><body>\n<header><h1>refspatial-gen audit</h1>"
        "<p>Judge each QA pair against the picture: <b>r</b> right · <b>w</b> wrong · <b>a</b> ambiguous · "
        '<b>n</b> note · <b>j/k</b> or arrows to move. <button onclick="download()">Download verdicts.jsonl</button> '
        '<span id="progress"></span></p></header>\n'
        f'<script type="application/json" id="items">{items_json}</script>\n{body}\n'
        f"<script>{_JS}</script></body></html>\n"
    )
