"""Run report: `report/report.json`, `report/report.html` and PNG plots, written at the end of every run.

Why: a data engineer decides from this page whether a run is usable before training on it: is the
relation / family / step mix what the recipe asked for, are answer points biased to one part of the
image, what was dropped and why, where did the time go, and how fast it ran. `refspatial-gen stats`
prints the same figures from the same dicts (see `summary_lines`).

Inputs are plain dicts (see docs/report.md): `stats` (deterministic dataset counts, as aggregated by
`run/stats.py`), `run_log` (timings and host facts, non-deterministic, kept out of the shards) and
`recipe_info` (name, hash, seed, code version...). Plots use matplotlib's object API with the Agg
canvas (no pyplot global state, headless), imported only when a report is written.
"""

from __future__ import annotations

import html
import json
import math
import re
from pathlib import Path
from typing import Any, Sequence

HEATMAP_BINS = 20
STAGES = ("load", "graph", "qa", "write")
REPORT_VERSION = 1

_REQUIRED = {"samples": int, "qa_pairs": int, "by_relation": dict, "by_family": dict, "by_steps": dict,
             "by_source": dict, "dropped": dict, "answer_heatmap": list}


# ---------------------------------------------------------------------------------------------- checks
def check_stats(stats: dict[str, Any]) -> None:
    """Raise ValueError naming the first malformed field: a report built on bad counts would mislead."""
    for key, typ in _REQUIRED.items():
        if key not in stats:
            raise ValueError(f"stats: missing {key!r}")
        if not isinstance(stats[key], typ) or (typ is int and isinstance(stats[key], bool)):
            raise ValueError(f"stats: {key!r} should be {typ.__name__}, got {type(stats[key]).__name__}")
    for key in ("by_relation", "by_family", "by_steps", "by_source", "dropped"):
        for k, v in stats[key].items():
            if not isinstance(v, int) or isinstance(v, bool) or v < 0:
                raise ValueError(f"stats: {key}[{k!r}] = {v!r} is not a count")
    hm = stats["answer_heatmap"]
    if len(hm) != HEATMAP_BINS or any(not isinstance(r, list) or len(r) != HEATMAP_BINS for r in hm):
        raise ValueError(f"stats: answer_heatmap must be {HEATMAP_BINS}x{HEATMAP_BINS}")
    if any(not isinstance(v, int) or isinstance(v, bool) or v < 0 for r in hm for v in r):
        raise ValueError("stats: answer_heatmap holds a value that is not a count")
    if stats["samples"] < 0 or stats["qa_pairs"] < 0:
        raise ValueError("stats: negative sample or QA count")


# ---------------------------------------------------------------------------------------------- derived
def location_bias(heatmap: Sequence[Sequence[int]]) -> dict[str, Any]:
    """How answer points spread over the image: mean, spread, a 3x3 share grid and normalised entropy.

    Entropy is 1.0 when points cover the 20x20 grid uniformly and 0.0 when they all fall in one cell;
    `thirds[r][c]` is the share in the image's r-th horizontal and c-th vertical third (row = y).
    Cells are assigned to thirds by their centre.
    """
    n = len(heatmap)
    total = sum(sum(r) for r in heatmap)
    if total == 0:
        return {"points": 0, "mean": None, "std": None, "thirds": None, "entropy": None}
    centre = [(i + 0.5) / n for i in range(n)]
    mx = sum(heatmap[i][j] * centre[j] for i in range(n) for j in range(n)) / total
    my = sum(heatmap[i][j] * centre[i] for i in range(n) for j in range(n)) / total
    sx = math.sqrt(sum(heatmap[i][j] * (centre[j] - mx) ** 2 for i in range(n) for j in range(n)) / total)
    sy = math.sqrt(sum(heatmap[i][j] * (centre[i] - my) ** 2 for i in range(n) for j in range(n)) / total)
    thirds = [[0] * 3 for _ in range(3)]
    for i in range(n):
        for j in range(n):
            thirds[min(2, int(centre[i] * 3))][min(2, int(centre[j] * 3))] += heatmap[i][j]
    ent = -sum((v / total) * math.log(v / total) for r in heatmap for v in r if v > 0) / math.log(n * n)
    r4 = lambda v: round(v, 4)  # noqa: E731
    return {"points": total, "mean": [r4(mx), r4(my)], "std": [r4(sx), r4(sy)],
            "thirds": [[r4(v / total) for v in row] for row in thirds], "entropy": r4(ent)}


def _sorted_counts(d: dict[str, int]) -> list[tuple[str, int]]:
    """Largest first, ties by name: readable and stable."""
    return sorted(((str(k), int(v)) for k, v in d.items()), key=lambda kv: (-kv[1], kv[0]))


def _steps_counts(d: dict[str, int]) -> list[tuple[str, int]]:
    keys = sorted(set(d) | {str(i) for i in range(1, 6)}, key=lambda k: (not str(k).isdigit(), int(k) if str(k).isdigit() else 0, str(k)))
    return [(str(k), int(d.get(k, 0))) for k in keys]


def silent_families(stats: dict[str, Any], recipe_info: dict[str, Any] | None) -> list[str]:
    """Families the recipe asks for (weight > 0) that produced no QA pair in the whole run.

    Why: a family that never fires is invisible in a table of counts; e.g. `identify` needs a support
    surface, which plain photos lack, so an image recipe that lists it silently gets none."""
    fams = (recipe_info or {}).get("families") or {}
    return sorted(f for f, w in fams.items() if float(w or 0) > 0 and not stats["by_family"].get(f))


def derived(stats: dict[str, Any], run_log: dict[str, Any], recipe_info: dict[str, Any] | None = None) -> dict[str, Any]:
    """Figures computed from the inputs that the page shows (also stored in report.json)."""
    dropped = sum(stats["dropped"].values())
    units = int(stats.get("units") or 0)
    wall = float(run_log.get("wall_seconds") or 0.0)
    return {
        "dropped_total": dropped,
        "drop_rate": round(dropped / units, 4) if units else None,
        "qa_per_sample": round(stats["qa_pairs"] / stats["samples"], 3) if stats["samples"] else None,
        "samples_per_s": round(stats["samples"] / wall, 3) if wall > 0 else None,
        "answer_location": location_bias(stats["answer_heatmap"]),
        "silent_families": silent_families(stats, recipe_info),
    }


# ---------------------------------------------------------------------------------------------- plots
def _figure(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, format="png", metadata={"Software": None})


def _hbar(path: Path, items: list[tuple[str, int]], title: str, xlabel: str, color: str) -> None:
    """Horizontal bars, first item on top, value written at each bar's end."""
    fig = _figure(8, max(1.6, 0.8 + 0.28 * len(items)))
    ax = fig.add_subplot()
    labels = [k for k, _ in items][::-1]
    vals = [v for _, v in items][::-1]
    bars = ax.barh(range(len(vals)), vals, color=color)
    ax.set_yticks(range(len(vals)), labels, fontsize=9)
    ax.bar_label(bars, labels=[f"{v:,}" for v in vals], padding=3, fontsize=8)
    ax.set_xlim(0, max(vals) * 1.15 if max(vals) > 0 else 1)
    ax.set_title(title, fontsize=11, loc="left")
    ax.set_xlabel(xlabel)
    ax.spines[["top", "right"]].set_visible(False)
    _save(fig, path)


def _vbar(path: Path, items: list[tuple[str, int | float]], title: str, xlabel: str, ylabel: str, color: str,
          fmt: str = "{:,}") -> None:
    fig = _figure(6, 3.2)
    ax = fig.add_subplot()
    vals = [v for _, v in items]
    bars = ax.bar(range(len(items)), vals, color=color)
    ax.set_xticks(range(len(items)), [k for k, _ in items])
    ax.bar_label(bars, labels=[fmt.format(v) for v in vals], padding=2, fontsize=8)
    ax.set_ylim(0, max(vals) * 1.18 if vals and max(vals) > 0 else 1)
    ax.set_title(title, fontsize=11, loc="left")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.spines[["top", "right"]].set_visible(False)
    _save(fig, path)


def _heatmap(path: Path, heatmap: list[list[int]], bias: dict[str, Any]) -> None:
    """The 20x20 answer-point counts over the normalised image (y down), with thirds and the mean."""
    import numpy as np

    hm = np.asarray(heatmap, dtype=float)
    fig = _figure(6.4, 5.2)
    ax = fig.add_subplot()
    im = ax.imshow(hm, extent=(0, 1, 1, 0), cmap="viridis", interpolation="nearest", vmin=0)
    for t in (1 / 3, 2 / 3):
        ax.axhline(t, color="white", lw=0.8, ls="--", alpha=0.7)
        ax.axvline(t, color="white", lw=0.8, ls="--", alpha=0.7)
    if bias["mean"] is not None:
        ax.plot(*bias["mean"], marker="+", color="#ff3df0", ms=14, mew=2, label="mean point")
        ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    ax.set_xlim(0, 1)
    ax.set_ylim(1, 0)
    ax.set_xlabel("x (normalised, left to right)")
    ax.set_ylabel("y (normalised, top to bottom)")
    ax.set_title(f"Answer points over the image ({int(hm.sum()):,} points)", fontsize=11, loc="left")
    fig.colorbar(im, ax=ax, label="answer points per cell")
    _save(fig, path)


def _stages(path: Path, stage_seconds: dict[str, float]) -> None:
    keys = [s for s in STAGES if s in stage_seconds] + sorted(k for k in stage_seconds if k not in STAGES)
    vals = [float(stage_seconds[k]) for k in keys]
    total = sum(vals)
    fig = _figure(8, 0.9 + 0.4 * len(keys))
    ax = fig.add_subplot()
    bars = ax.barh(range(len(keys)), vals[::-1], color="#6a51a3")
    ax.set_yticks(range(len(keys)), keys[::-1])
    ax.bar_label(bars, labels=[f"{v:,.1f} s ({100 * v / total:.0f}%)" if total > 0 else f"{v:.1f} s" for v in vals[::-1]],
                 padding=3, fontsize=8)
    ax.set_xlim(0, max(vals) * 1.3 if vals and max(vals) > 0 else 1)
    ax.set_xlabel("seconds (summed over workers)")
    ax.set_title("Time per stage", fontsize=11, loc="left")
    ax.spines[["top", "right"]].set_visible(False)
    _save(fig, path)


def _throughput(path: Path, run_log: dict[str, Any]) -> None:
    """Units/s and QA/s for the run, and per worker (what adding a worker should add)."""
    workers = max(1, int(run_log.get("workers") or 1))
    ups, qps = float(run_log.get("units_per_s") or 0.0), float(run_log.get("qa_per_s") or 0.0)
    fig = _figure(8, 3.0)
    for k, (name, v, c) in enumerate((("units / s", ups, "#2171b5"), ("QA pairs / s", qps, "#238b45"))):
        ax = fig.add_subplot(1, 2, k + 1)
        bars = ax.bar([0, 1], [v, v / workers], color=[c, c], alpha=1.0)
        bars[1].set_alpha(0.55)
        ax.set_xticks([0, 1], ["run", f"per worker\n({workers} worker{'s' if workers != 1 else ''})"])
        ax.bar_label(bars, labels=[f"{v:,.2f}", f"{v / workers:,.2f}"], padding=2, fontsize=8)
        ax.set_ylim(0, v * 1.2 if v > 0 else 1)
        ax.set_title(name, fontsize=11, loc="left")
        ax.spines[["top", "right"]].set_visible(False)
    _save(fig, path)


def write_plots(report_dir: Path, stats: dict[str, Any], run_log: dict[str, Any], bias: dict[str, Any]) -> dict[str, str]:
    """Every plot that has data; returns {plot key: file name}. Empty inputs get no plot (the page says so)."""
    plots: dict[str, str] = {}

    def add(key: str, fn, *args) -> None:
        name = f"{key}.png"
        fn(report_dir / name, *args)
        plots[key] = name

    if stats["by_relation"]:
        add("qa_by_relation", _hbar, _sorted_counts(stats["by_relation"]), "QA pairs per relation", "QA pairs", "#2171b5")
    if stats["by_family"]:
        add("qa_by_family", _hbar, _sorted_counts(stats["by_family"]), "QA pairs per question family", "QA pairs", "#238b45")
    if any(stats["by_steps"].values()):
        add("qa_by_steps", _vbar, _steps_counts(stats["by_steps"]), "QA pairs per step count", "reasoning steps",
            "QA pairs", "#fd8d3c")
    if stats["by_source"]:
        add("qa_by_source", _hbar, _sorted_counts(stats["by_source"]), "QA pairs per source", "QA pairs", "#807dba")
    if bias["points"]:
        add("answer_heatmap", _heatmap, stats["answer_heatmap"], bias)
    if any(stats["dropped"].values()):
        add("dropped_by_reason", _hbar, _sorted_counts(stats["dropped"]), "Dropped units by reason", "units", "#cb181d")
    if run_log.get("stage_seconds"):
        add("time_per_stage", _stages, run_log["stage_seconds"])
    if run_log.get("units_per_s") is not None or run_log.get("qa_per_s") is not None:
        add("throughput", _throughput, run_log)
    return plots


# ---------------------------------------------------------------------------------------------- text
def _fmt_rate(v: Any, unit: str = "/s") -> str:
    return "-" if v is None else f"{float(v):,.2f}{unit}"


def summary_lines(stats: dict[str, Any], run_log: dict[str, Any] | None = None,
                  recipe_info: dict[str, Any] | None = None) -> list[str]:
    """The header figures as plain text lines (what `stats` prints and the page's summary shows)."""
    run_log = run_log or {}
    d = derived(stats, run_log, recipe_info)
    lines = [f"samples     {stats['samples']:,}", f"QA pairs    {stats['qa_pairs']:,}"
             + (f"  ({d['qa_per_sample']} per sample)" if d["qa_per_sample"] is not None else "")]
    drop = f"dropped     {d['dropped_total']:,}"
    if d["drop_rate"] is not None:
        drop += f" of {stats.get('units', 0):,} units ({100 * d['drop_rate']:.1f}%)"
    lines.append(drop)
    if run_log:
        lines.append(f"QA/s        {_fmt_rate(run_log.get('qa_per_s'), '')}   units/s {_fmt_rate(run_log.get('units_per_s'), '')}")
        lines.append(f"wall time   {float(run_log.get('wall_seconds') or 0):,.1f} s on {run_log.get('workers', '?')} "
                     f"worker(s), executor {run_log.get('executor', '?')}")
    if d["silent_families"]:
        lines.append(f"warning     families that produced no QA pair: {', '.join(d['silent_families'])}")
    loc = d["answer_location"]
    if loc["points"]:
        lines.append(f"answers     mean point ({loc['mean'][0]:.3f}, {loc['mean'][1]:.3f}), "
                     f"spread entropy {loc['entropy']:.2f} (1 = uniform)")
    return lines


_CSS = """
body{font-family:system-ui,-apple-system,"DejaVu Sans",sans-serif;margin:0;background:#f4f5f7;color:#1d1f23;line-height:1.4}
header{background:#1d1f23;color:#fff;padding:18px 28px}header h1{margin:0 0 4px;font-size:22px}
header .sub{color:#aab;font-size:13px}
.cards{display:flex;flex-wrap:wrap;gap:12px;margin-top:14px}
.card{background:#2b2e35;border-radius:6px;padding:8px 14px;min-width:120px}
.card .v{font-size:22px;font-weight:700}.card .k{font-size:12px;color:#aab;text-transform:uppercase;letter-spacing:.04em}
.card.bad .v{color:#ff8a80}
main{padding:8px 28px 40px;max-width:1200px}
section{background:#fff;border-radius:6px;box-shadow:0 1px 3px rgba(0,0,0,.12);padding:14px 18px;margin:16px 0}
section h2{font-size:17px;margin:0 0 8px}
.row{display:flex;flex-wrap:wrap;gap:18px;align-items:flex-start}.row>div.text{flex:1 1 320px;min-width:280px}
img{max-width:100%;height:auto;border:1px solid #e3e4e8}
table{border-collapse:collapse;font-size:13px}pre{white-space:pre-wrap;font-size:12px;background:#f6f6f8;padding:6px}td,th{padding:2px 10px 2px 0;text-align:left;vertical-align:top}
th{color:#555;font-weight:600}td.n{text-align:right;font-variant-numeric:tabular-nums}
.muted{color:#777;font-size:13px}
table.grid td{width:64px;text-align:center;border:1px solid #ddd;padding:4px}
"""


def _cell(v: Any, limit: int = 160) -> str:
    """A value as short text for a table cell: lists of records one per line, long text cut."""
    if isinstance(v, list) and all(isinstance(x, dict) for x in v) and v:
        text = "; ".join(json.dumps(x, sort_keys=True) for x in v)
    elif isinstance(v, (dict, list)):
        text = json.dumps(v, sort_keys=True)
    else:
        text = str(v)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _table(rows: Sequence[tuple[str, Any]], header: tuple[str, str] | None = None) -> str:
    e = html.escape
    head = f"<tr><th>{e(header[0])}</th><th>{e(header[1])}</th></tr>" if header else ""
    def cell(v: Any) -> str:
        text = v if isinstance(v, str) else f"{v:,}"
        numeric = re.fullmatch(r"[-+]?[\d,]*\.?\d+( ?(s|%|MB|/s))?", text) is not None
        return f'<td class="n">{e(text)}</td>' if numeric else f"<td>{e(text)}</td>"

    body = "".join(f"<tr><td>{e(str(k))}</td>{cell(v)}</tr>" for k, v in rows)
    return f"<table>{head}{body}</table>"


def _img(plots: dict[str, str], key: str, alt: str) -> str:
    if key not in plots:
        return ""
    return f'<img src="{html.escape(plots[key])}" alt="{html.escape(alt)}">'


def _section(title: str, body: str) -> str:
    return f"<section><h2>{html.escape(title)}</h2>{body}</section>"


def render_html(report: dict[str, Any]) -> str:
    """The page for a report dict (as stored in report.json): header summary, then one section per plot."""
    e = html.escape
    stats, run_log, recipe, d, plots = (report["stats"], report["run_log"], report["recipe"], report["derived"],
                                        report["plots"])
    title = f"refspatial-gen run report: {recipe.get('name') or recipe.get('recipe') or 'run'}"
    cards = [("samples", f"{stats['samples']:,}", False), ("QA pairs", f"{stats['qa_pairs']:,}", False),
             ("dropped", f"{d['dropped_total']:,}" + (f" ({100 * d['drop_rate']:.1f}%)" if d["drop_rate"] is not None else ""),
              d["dropped_total"] > 0),
             ("QA / s", _fmt_rate(run_log.get("qa_per_s"), ""), False),
             ("units / s", _fmt_rate(run_log.get("units_per_s"), ""), False),
             ("wall time", f"{float(run_log.get('wall_seconds') or 0):,.1f} s", False)]
    if run_log.get("errors"):
        cards.append(("internal errors", f"{len(run_log['errors']):,}", True))
    card_html = "".join(f'<div class="card{" bad" if bad else ""}"><div class="v">{e(v)}</div><div class="k">{e(k)}</div></div>'
                        for k, v, bad in cards)
    sub = " · ".join(e(str(x)) for x in (
        f"{run_log.get('workers', '?')} worker(s), executor {run_log.get('executor', '?')}",
        f"started {run_log.get('started', '?')}", f"host {run_log.get('host', '?')}",
        f"seed {recipe.get('seed', '?')}") if x)
    parts = [f"<header><h1>{e(title)}</h1><div class=\"sub\">{sub}</div><div class=\"cards\">{card_html}</div></header><main>"]

    recipe_rows = [(k, _cell(v)) for k, v in sorted(recipe.items())]
    run_rows = [(k, f"{v:,.3f}" if isinstance(v, float) else _cell(v)) for k, v in sorted(run_log.items())
                if k not in ("stage_seconds", "errors")]
    errors = run_log.get("errors") or []
    run_rows.append(("internal errors", str(len(errors))))
    parts.append(_section("Run", '<div class="row">' + _table(recipe_rows, ("recipe", "")) + _table(run_rows, ("run", ""))
                          + _table([("units planned", f"{stats.get('units', 0):,}"),
                                    ("QA pairs per sample", str(d["qa_per_sample"] if d["qa_per_sample"] is not None else "-")),
                                    ("samples / s", _fmt_rate(d["samples_per_s"], ""))], ("dataset", "")) + "</div>"))

    def counts_section(title: str, key: str, counts: list[tuple[str, int]], empty: str) -> None:
        if not counts or not any(v for _, v in counts):
            parts.append(_section(title, f'<p class="muted">{e(empty)}</p>'))
            return
        parts.append(_section(title, f'<div class="row">{_img(plots, key, title)}{_table(counts, ("", "QA pairs"))}</div>'))

    counts_section("QA pairs per relation", "qa_by_relation", _sorted_counts(stats["by_relation"]), "No relation was asked.")
    counts_section("QA pairs per question family", "qa_by_family", _sorted_counts(stats["by_family"]), "No QA pairs.")
    if d.get("silent_families"):
        parts.append(_section("Families that produced nothing",
                              f"<p><b>{e(', '.join(d['silent_families']))}</b>: the recipe asks for "
                              f"{'this family' if len(d['silent_families']) == 1 else 'these families'}, but no "
                              "template found an instance in any sample. Typical causes: the templates need "
                              "something this source lacks (e.g. <code>identify</code> and placement need a "
                              "support surface, which plain photos do not have), or every candidate failed a check. "
                              "Remove the family from the recipe or change the source.</p>"))
    counts_section("QA pairs per step count", "qa_by_steps", _steps_counts(stats["by_steps"]), "No QA pairs.")
    counts_section("QA pairs per source", "qa_by_source", _sorted_counts(stats["by_source"]), "No QA pairs.")

    loc = d["answer_location"]
    if loc["points"]:
        grid = "".join("<tr>" + "".join(f"<td>{100 * v:.1f}%</td>" for v in row) + "</tr>" for row in loc["thirds"])
        expl = (f"<p>{loc['points']:,} answer points. Mean point ({loc['mean'][0]:.3f}, {loc['mean'][1]:.3f}), "
                f"standard deviation ({loc['std'][0]:.3f}, {loc['std'][1]:.3f}); spread entropy {loc['entropy']:.2f} "
                "(1 = uniform over the 20&times;20 grid, 0 = one cell). A model trained on a skewed set learns to "
                "guess where answers usually are.</p><p>Share of answer points per third of the image:</p>"
                f'<table class="grid">{grid}</table>')
        parts.append(_section("Answer-point location bias", f'<div class="row">{_img(plots, "answer_heatmap", "answer point heat map")}<div class="text">{expl}</div></div>'))
    else:
        parts.append(_section("Answer-point location bias", '<p class="muted">No point answers.</p>'))

    drops = _sorted_counts(stats["dropped"])
    if drops and any(v for _, v in drops):
        parts.append(_section("Dropped units by reason",
                              f'<div class="row">{_img(plots, "dropped_by_reason", "drops by reason")}{_table(drops, ("reason", "units"))}</div>'))
    else:
        parts.append(_section("Dropped units by reason", '<p class="muted">No unit was dropped.</p>'))
    truth = _sorted_counts(stats.get("truth") or {})
    if truth and any(v for _, v in truth):
        parts.append(_section("Truth checks: objects and questions withheld, by reason",
                              "<p>Objects a source removed, objects the scene graph kept out of questions, and "
                              "questions rejected, because the scene model disagreed with independent evidence "
                              "(size ranges, visibility, depth, instance labels). Thresholds are in the recipe.</p>"
                              + _table(truth, ("reason", "count"))))
    else:
        parts.append(_section("Truth checks", '<p class="muted">No truth check withheld anything.</p>'))

    st = run_log.get("stage_seconds") or {}
    if st:
        rows = [(k, f"{float(v):,.2f} s") for k, v in st.items()]
        parts.append(_section("Time per stage", f'<div class="row">{_img(plots, "time_per_stage", "time per stage")}{_table(rows)}</div>'))
    if "throughput" in plots:
        rows = [("units / s", _fmt_rate(run_log.get("units_per_s"), "")), ("QA pairs / s", _fmt_rate(run_log.get("qa_per_s"), "")),
                ("workers", str(run_log.get("workers", "?"))),
                ("peak RSS per worker", f"{float(run_log.get('peak_rss_mb_per_worker') or 0):,.0f} MB")]
        parts.append(_section("Throughput", f'<div class="row">{_img(plots, "throughput", "throughput")}{_table(rows)}</div>'))
    if errors:
        items = "".join(f"<pre>{e(_cell(x, 4000))}</pre>" for x in errors[:20])
        more = f"<p class=\"muted\">... and {len(errors) - 20} more in run_log.json</p>" if len(errors) > 20 else ""
        parts.append(_section(f"Internal errors ({len(errors)})",
                              "<p>Units that failed with an unexpected exception (counted as dropped). "
                              f"These are bugs, not bad input.</p><details><summary>tracebacks</summary>{items}{more}</details>"))
    parts.append('<p class="muted">Written by refspatial-gen. Figures in report.json; plots are PNG files beside this page.</p></main>')
    return (f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>'
            f"<style>{_CSS}</style></head><body>\n" + "\n".join(parts) + "\n</body></html>\n")


# ---------------------------------------------------------------------------------------------- entry
def build_report(stats: dict[str, Any], run_log: dict[str, Any], recipe_info: dict[str, Any],
                 plots: dict[str, str] | None = None) -> dict[str, Any]:
    """The report.json content (checks `stats` first)."""
    check_stats(stats)
    return {"report_version": REPORT_VERSION, "stats": stats, "run_log": dict(run_log), "recipe": dict(recipe_info),
            "derived": derived(stats, run_log, recipe_info), "plots": dict(sorted((plots or {}).items()))}


def write_report(out_dir: Path, stats: dict[str, Any], run_log: dict[str, Any], recipe_info: dict[str, Any]) -> Path:
    """Write `out_dir/report/{report.json, report.html, *.png}`; returns the path of report.html."""
    report_dir = Path(out_dir) / "report"
    report_dir.mkdir(parents=True, exist_ok=True)
    report = build_report(stats, run_log, recipe_info)
    for old in report_dir.glob("*.png"):  # a re-run must not leave plots of the previous one
        old.unlink()
    report["plots"] = write_plots(report_dir, stats, run_log, report["derived"]["answer_location"])
    (report_dir / "report.json").write_text(json.dumps(report, sort_keys=True, indent=1, ensure_ascii=False) + "\n",
                                            encoding="utf-8")
    page = report_dir / "report.html"
    page.write_text(render_html(report), encoding="utf-8")
    return page


def load_report(path: Path) -> dict[str, Any]:
    """Read a report.json (or the folder holding `report/report.json`)."""
    p = Path(path)
    if p.is_dir():
        p = p / "report" / "report.json" if (p / "report" / "report.json").is_file() else p / "report.json"
    return json.loads(p.read_text(encoding="utf-8"))
