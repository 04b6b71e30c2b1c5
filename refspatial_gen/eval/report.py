"""`eval --out DIR`: `report.json`, `index.html` and PNG plots of one evaluation (matplotlib Agg, headless)."""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from refspatial_gen.run.report_plots import agg_figure  # the run report's Agg figure (no pyplot state)


def _rates_plot(path: Path, rows: dict[str, dict], title: str, xlabel: str) -> None:
    """Horizontal bars of success rate with 95 % interval whiskers, n beside each bar."""
    keys = list(rows)[::-1]
    fig = agg_figure(8, max(1.8, 0.9 + 0.3 * len(keys)))
    ax = fig.add_subplot()
    rates = [rows[k]["success_rate"] for k in keys]
    lo = [max(0.0, rows[k]["success_rate"] - rows[k]["ci95"][0]) for k in keys]  # rounded apart: no -1e-4
    hi = [max(0.0, rows[k]["ci95"][1] - rows[k]["success_rate"]) for k in keys]
    ax.barh(range(len(keys)), rates, xerr=[lo, hi], color="#4c72b0", ecolor="#333333", capsize=3)
    ax.set_yticks(range(len(keys)), [f"{k}  (n={rows[k]['n']})" for k in keys], fontsize=9)
    ax.set_xlim(0, 1.0)
    ax.set_xlabel(xlabel)
    ax.set_title(title, fontsize=11, loc="left")
    ax.spines[["top", "right"]].set_visible(False)
    fig.tight_layout()
    fig.savefig(path, format="png", metadata={"Software": None})


def _components_plot(path: Path, comps: dict[str, dict]) -> None:
    keys = [k for k in comps if comps[k]["mean"] is not None]
    fig = agg_figure(6, 2.6)
    ax = fig.add_subplot()
    bars = ax.bar(keys, [comps[k]["mean"] for k in keys], color="#55a868")
    ax.bar_label(
        bars, labels=[f"{comps[k]['mean']:.3f}\n(w {comps[k]['weight']}, n {comps[k]['n']})" for k in keys], fontsize=8
    )
    ax.set_ylim(0, 1.3)
    ax.set_title("reward components (mean over QA pairs they apply to)", fontsize=11, loc="left")
    ax.spines[["top", "right"]].set_visible(False)
    fig.tight_layout()
    fig.savefig(path, format="png", metadata={"Software": None})


def _table(rows: dict[str, dict], name: str) -> str:
    body = "".join(
        f"<tr><td>{html.escape(k)}</td><td>{r['n']}</td><td>{r['success_rate']:.3f}</td>"
        f"<td>[{r['ci95'][0]:.3f}, {r['ci95'][1]:.3f}]</td><td>{r['reward']:.3f}</td>"
        f"<td>{r['parse_failures']}</td></tr>"
        for k, r in rows.items()
    )
    return (
        f"<table><tr><th>{html.escape(name)}</th><th>n</th><th>success</th><th>95% interval</th>"
        f"<th>reward (norm.)</th><th>parse failures</th></tr>{body}</table>"
    )


def write_report(
    out: Path | str,
    summary: dict[str, Any],
    info: dict[str, Any],
    problem_lines: list[str],
    audit_rows: list[dict] | None = None,
) -> Path:
    """Write the report folder; returns the HTML path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "report.json").write_text(
        json.dumps({"info": info, "summary": summary, "audit": audit_rows}, indent=1, sort_keys=True)
    )
    plots = {"family": "by_family.png", "steps": "by_steps.png", "split": "by_split.png", "relation": "by_relation.png"}
    for g, f in plots.items():
        if summary.get(f"by_{g}"):
            _rates_plot(out / f, summary[f"by_{g}"], f"success by {g} (95% Wilson intervals)", "success rate")
    _components_plot(out / "components.png", summary["components"])
    p = summary["problems"]
    parts = [
        f"<h1>refspatial-gen eval</h1><p>dataset <code>{html.escape(str(info.get('dataset')))}</code>, predictions "
        f"<code>{html.escape(str(info.get('predictions')))}</code>, reward variant "
        f"{html.escape(str(info.get('variant')))}</p>",
        f"<h2>Overall</h2><p><b>success {summary['success_rate']:.3f}</b> "
        f"[{summary['ci95'][0]:.3f}, {summary['ci95'][1]:.3f}] "
        f"over n = {summary['n']} QA pairs; normalised reward {summary['reward']:.3f}; parse failures "
        f"{summary['parse_failures']}; missing {p['missing_ids']}; unknown ids {p['unknown_ids']}; duplicate ids "
        f"{p['duplicate_ids']}; malformed lines {p['malformed_lines']}</p>",
    ]
    if problem_lines:
        parts.append(
            "<h2>Problems in the predictions file</h2><pre>" + html.escape("\n".join(problem_lines)) + "</pre>"
        )
    parts.append('<h2>Reward components</h2><img src="components.png">')
    for g in ("family", "steps", "split", "source", "relation", "template"):
        rows = summary.get(f"by_{g}") or {}
        img = f'<img src="{plots[g]}"><br>' if g in plots and rows else ""
        parts.append(f"<h2>By {g}</h2>{img}{_table(rows, g)}")
    if audit_rows:

        def chance(r: dict) -> str:
            return "" if r["chance"] is None else f"{r['chance']:.3f}"

        body = "".join(
            f"<tr><td>{html.escape(r['template'])}</td><td>{r['n']}</td><td>{chance(r)}</td>"
            f"<td>{r['text-only']['success_rate']:.3f}</td><td>{r['frequent-choice']['success_rate']:.3f}</td>"
            f"<td>{'LEAKS' if r['leaks'] else ''}</td></tr>"
            for r in audit_rows
        )
        parts.append(
            "<h2>Shortcut audit</h2><table><tr><th>template</th><th>n</th><th>chance</th><th>text-only</th>"
            f"<th>frequent-choice</th><th></th></tr>{body}</table>"
        )
    style = (
        "<style>body{font-family:sans-serif;max-width:1000px;margin:2em auto}table{border-collapse:collapse;"
        "margin-bottom:1em}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}td:first-child,"
        "th:first-child{text-align:left}</style>"
    )
    path = out / "index.html"
    path.write_text(
        f"<!doctype html><html><head><meta charset='utf-8'><title>eval</title>{style}</head><body>"
        + "\n".join(parts)
        + "</body></html>"
    )
    return path
