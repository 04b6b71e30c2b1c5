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

import json
from pathlib import Path
from typing import Any

from refspatial_gen.run.report_data import (
    HEATMAP_BINS,
    STAGES,
    check_stats,
    derived,
    location_bias,
    silent_families,
    summary_lines,
)
from refspatial_gen.run.report_html import render_html
from refspatial_gen.run.report_plots import write_plots

__all__ = [
    "HEATMAP_BINS",
    "REPORT_VERSION",
    "STAGES",
    "build_report",
    "check_stats",
    "derived",
    "load_report",
    "location_bias",
    "render_html",
    "silent_families",
    "summary_lines",
    "write_plots",
    "write_report",
]

REPORT_VERSION = 1


def build_report(
    stats: dict[str, Any], run_log: dict[str, Any], recipe_info: dict[str, Any], plots: dict[str, str] | None = None
) -> dict[str, Any]:
    """The report.json content (checks `stats` first)."""
    check_stats(stats)
    return {
        "report_version": REPORT_VERSION,
        "stats": stats,
        "run_log": dict(run_log),
        "recipe": dict(recipe_info),
        "derived": derived(stats, run_log, recipe_info),
        "plots": dict(sorted((plots or {}).items())),
    }


def write_report(out_dir: Path, stats: dict[str, Any], run_log: dict[str, Any], recipe_info: dict[str, Any]) -> Path:
    """Write `out_dir/report/{report.json, report.html, *.png}`; returns the path of report.html."""
    report_dir = Path(out_dir) / "report"
    report_dir.mkdir(parents=True, exist_ok=True)
    report = build_report(stats, run_log, recipe_info)
    for old in report_dir.glob("*.png"):  # a re-run must not leave plots of the previous one
        old.unlink()
    report["plots"] = write_plots(report_dir, stats, run_log, report["derived"]["answer_location"])
    (report_dir / "report.json").write_text(
        json.dumps(report, sort_keys=True, indent=1, ensure_ascii=False) + "\n", encoding="utf-8"
    )
    page = report_dir / "report.html"
    page.write_text(render_html(report), encoding="utf-8")
    return page


def load_report(path: Path) -> dict[str, Any]:
    """Read a report.json (or the folder holding `report/report.json`)."""
    p = Path(path)
    if p.is_dir():
        p = p / "report" / "report.json" if (p / "report" / "report.json").is_file() else p / "report.json"
    return json.loads(p.read_text(encoding="utf-8"))
