"""The run report's self-contained page (report.html) from a report dict: a header summary, then one
section per figure with its plot and its table (run/report.py)."""

from __future__ import annotations

import html
import json
import re
from collections.abc import Sequence
from typing import Any

from refspatial_gen.run.report_data import fmt_rate, sorted_counts, steps_counts

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
"""  # noqa: E501 (CSS rules one per line, as the page carries them)


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
    stats, run_log, recipe, d, plots = (
        report["stats"],
        report["run_log"],
        report["recipe"],
        report["derived"],
        report["plots"],
    )
    title = f"refspatial-gen run report: {recipe.get('name') or recipe.get('recipe') or 'run'}"
    parts = [_header(title, stats, run_log, recipe, d), _run_section(stats, run_log, recipe, d)]
    parts += _count_sections(stats, d, plots)
    parts.append(_location_section(d["answer_location"], plots))
    parts += _drop_sections(stats, plots)
    parts += _timing_sections(run_log, plots)
    parts.append(
        '<p class="muted">Written by refspatial-gen. Figures in report.json; '
        "plots are PNG files beside this page.</p></main>"
    )
    return (
        f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>{e(title)}</title>'
        f"<style>{_CSS}</style></head><body>\n" + "\n".join(parts) + "\n</body></html>\n"
    )


def _header(
    title: str, stats: dict[str, Any], run_log: dict[str, Any], recipe: dict[str, Any], d: dict[str, Any]
) -> str:
    """The dark header: title, run facts and the headline cards."""
    e = html.escape
    cards = [
        ("samples", f"{stats['samples']:,}", False),
        ("QA pairs", f"{stats['qa_pairs']:,}", False),
        (
            "dropped",
            f"{d['dropped_total']:,}" + (f" ({100 * d['drop_rate']:.1f}%)" if d["drop_rate"] is not None else ""),
            d["dropped_total"] > 0,
        ),
        ("QA / s", fmt_rate(run_log.get("qa_per_s"), ""), False),
        ("units / s", fmt_rate(run_log.get("units_per_s"), ""), False),
        ("wall time", f"{float(run_log.get('wall_seconds') or 0):,.1f} s", False),
    ]
    if run_log.get("errors"):
        cards.append(("internal errors", f"{len(run_log['errors']):,}", True))
    card_html = "".join(
        f'<div class="card{" bad" if bad else ""}"><div class="v">{e(v)}</div><div class="k">{e(k)}</div></div>'
        for k, v, bad in cards
    )
    sub = " · ".join(
        e(str(x))
        for x in (
            f"{run_log.get('workers', '?')} worker(s), executor {run_log.get('executor', '?')}",
            f"started {run_log.get('started', '?')}",
            f"host {run_log.get('host', '?')}",
            f"seed {recipe.get('seed', '?')}",
        )
        if x
    )
    return f'<header><h1>{e(title)}</h1><div class="sub">{sub}</div><div class="cards">{card_html}</div></header><main>'


def _run_section(stats: dict[str, Any], run_log: dict[str, Any], recipe: dict[str, Any], d: dict[str, Any]) -> str:
    """The recipe, the run's facts and the dataset's headline figures, as three tables."""
    recipe_rows = [(k, _cell(v)) for k, v in sorted(recipe.items())]
    run_rows = [
        (k, f"{v:,.3f}" if isinstance(v, float) else _cell(v))
        for k, v in sorted(run_log.items())
        if k not in ("stage_seconds", "errors")
    ]
    errors = run_log.get("errors") or []
    run_rows.append(("internal errors", str(len(errors))))
    return _section(
        "Run",
        '<div class="row">'
        + _table(recipe_rows, ("recipe", ""))
        + _table(run_rows, ("run", ""))
        + _table(
            [
                ("units planned", f"{stats.get('units', 0):,}"),
                ("QA pairs per sample", str(d["qa_per_sample"] if d["qa_per_sample"] is not None else "-")),
                ("samples / s", fmt_rate(d["samples_per_s"], "")),
            ],
            ("dataset", ""),
        )
        + "</div>",
    )


def _count_sections(stats: dict[str, Any], d: dict[str, Any], plots: dict[str, str]) -> list[str]:
    """QA pairs per relation, family (and the families that produced nothing), step count and source."""
    e = html.escape
    parts: list[str] = []

    def counts_section(title: str, key: str, counts: list[tuple[str, int]], empty: str) -> None:
        if not counts or not any(v for _, v in counts):
            parts.append(_section(title, f'<p class="muted">{e(empty)}</p>'))
            return
        parts.append(
            _section(title, f'<div class="row">{_img(plots, key, title)}{_table(counts, ("", "QA pairs"))}</div>')
        )

    counts_section(
        "QA pairs per relation", "qa_by_relation", sorted_counts(stats["by_relation"]), "No relation was asked."
    )
    counts_section("QA pairs per question family", "qa_by_family", sorted_counts(stats["by_family"]), "No QA pairs.")
    if d.get("silent_families"):
        parts.append(
            _section(
                "Families that produced nothing",
                f"<p><b>{e(', '.join(d['silent_families']))}</b>: the recipe asks for "
                f"{'this family' if len(d['silent_families']) == 1 else 'these families'}, but no "
                "template found an instance in any sample. Typical causes: the templates need "
                "something this source lacks (e.g. <code>identify</code> and placement need a "
                "support surface, which plain photos do not have), or every candidate failed a check. "
                "Remove the family from the recipe or change the source.</p>",
            )
        )
    counts_section("QA pairs per step count", "qa_by_steps", steps_counts(stats["by_steps"]), "No QA pairs.")
    counts_section("QA pairs per source", "qa_by_source", sorted_counts(stats["by_source"]), "No QA pairs.")
    return parts


def _location_section(loc: dict[str, Any], plots: dict[str, str]) -> str:
    """Where answer points fall: the heat map, the mean and spread, and the share per third of the image."""
    if not loc["points"]:
        return _section("Answer-point location bias", '<p class="muted">No point answers.</p>')
    grid = "".join("<tr>" + "".join(f"<td>{100 * v:.1f}%</td>" for v in row) + "</tr>" for row in loc["thirds"])
    expl = (
        f"<p>{loc['points']:,} answer points. Mean point ({loc['mean'][0]:.3f}, {loc['mean'][1]:.3f}), "
        f"standard deviation ({loc['std'][0]:.3f}, {loc['std'][1]:.3f}); spread entropy {loc['entropy']:.2f} "
        "(1 = uniform over the 20&times;20 grid, 0 = one cell). A model trained on a skewed set learns to "
        "guess where answers usually are.</p><p>Share of answer points per third of the image:</p>"
        f'<table class="grid">{grid}</table>'
    )
    return _section(
        "Answer-point location bias",
        f'<div class="row">{_img(plots, "answer_heatmap", "answer point heat map")}'
        f'<div class="text">{expl}</div></div>',
    )


def _drop_sections(stats: dict[str, Any], plots: dict[str, str]) -> list[str]:
    """Dropped units by reason, and what the truth checks withheld."""
    parts = []
    drops = sorted_counts(stats["dropped"])
    if drops and any(v for _, v in drops):
        parts.append(
            _section(
                "Dropped units by reason",
                f'<div class="row">{_img(plots, "dropped_by_reason", "drops by reason")}'
                f"{_table(drops, ('reason', 'units'))}</div>",
            )
        )
    else:
        parts.append(_section("Dropped units by reason", '<p class="muted">No unit was dropped.</p>'))
    truth = sorted_counts(stats.get("truth") or {})
    if truth and any(v for _, v in truth):
        parts.append(
            _section(
                "Truth checks: objects and questions withheld, by reason",
                "<p>Objects a source removed, objects the scene graph kept out of questions, and "
                "questions rejected, because the scene model disagreed with independent evidence "
                "(size ranges, visibility, depth, instance labels). Thresholds are in the recipe.</p>"
                + _table(truth, ("reason", "count")),
            )
        )
    else:
        parts.append(_section("Truth checks", '<p class="muted">No truth check withheld anything.</p>'))
    return parts


def _timing_sections(run_log: dict[str, Any], plots: dict[str, str]) -> list[str]:
    """Time per stage, throughput, and the internal errors (tracebacks folded away)."""
    e = html.escape
    parts = []
    errors = run_log.get("errors") or []
    st = run_log.get("stage_seconds") or {}
    if st:
        rows = [(k, f"{float(v):,.2f} s") for k, v in st.items()]
        parts.append(
            _section(
                "Time per stage",
                f'<div class="row">{_img(plots, "time_per_stage", "time per stage")}{_table(rows)}</div>',
            )
        )
    if "throughput" in plots:
        rows = [
            ("units / s", fmt_rate(run_log.get("units_per_s"), "")),
            ("QA pairs / s", fmt_rate(run_log.get("qa_per_s"), "")),
            ("workers", str(run_log.get("workers", "?"))),
            ("peak RSS per worker", f"{float(run_log.get('peak_rss_mb_per_worker') or 0):,.0f} MB"),
        ]
        parts.append(
            _section("Throughput", f'<div class="row">{_img(plots, "throughput", "throughput")}{_table(rows)}</div>')
        )
    if errors:
        items = "".join(f"<pre>{e(_cell(x, 4000))}</pre>" for x in errors[:20])
        more = f'<p class="muted">... and {len(errors) - 20} more in run_log.json</p>' if len(errors) > 20 else ""
        parts.append(
            _section(
                f"Internal errors ({len(errors)})",
                "<p>Units that failed with an unexpected exception (counted as dropped). "
                f"These are bugs, not bad input.</p><details><summary>tracebacks</summary>{items}{more}</details>",
            )
        )
    return parts
