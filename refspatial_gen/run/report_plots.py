"""The run report's PNG plots, with matplotlib's object API on the Agg canvas (no pyplot global state,
headless; imported only when a plot is drawn). Empty inputs get no plot: the page says so instead."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from refspatial_gen.run.report_data import STAGES, sorted_counts, steps_counts


def agg_figure(w: float, h: float):
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
    fig = agg_figure(8, max(1.6, 0.8 + 0.28 * len(items)))
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


def _vbar(
    path: Path,
    items: list[tuple[str, int | float]],
    title: str,
    xlabel: str,
    ylabel: str,
    color: str,
    fmt: str = "{:,}",
) -> None:
    fig = agg_figure(6, 3.2)
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
    fig = agg_figure(6.4, 5.2)
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
    fig = agg_figure(8, 0.9 + 0.4 * len(keys))
    ax = fig.add_subplot()
    bars = ax.barh(range(len(keys)), vals[::-1], color="#6a51a3")
    ax.set_yticks(range(len(keys)), keys[::-1])
    ax.bar_label(
        bars,
        labels=[f"{v:,.1f} s ({100 * v / total:.0f}%)" if total > 0 else f"{v:.1f} s" for v in vals[::-1]],
        padding=3,
        fontsize=8,
    )
    ax.set_xlim(0, max(vals) * 1.3 if vals and max(vals) > 0 else 1)
    ax.set_xlabel("seconds (summed over workers)")
    ax.set_title("Time per stage", fontsize=11, loc="left")
    ax.spines[["top", "right"]].set_visible(False)
    _save(fig, path)


def _throughput(path: Path, run_log: dict[str, Any]) -> None:
    """Units/s and QA/s for the run, and per worker (what adding a worker should add)."""
    workers = max(1, int(run_log.get("workers") or 1))
    ups, qps = float(run_log.get("units_per_s") or 0.0), float(run_log.get("qa_per_s") or 0.0)
    fig = agg_figure(8, 3.0)
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


def write_plots(
    report_dir: Path, stats: dict[str, Any], run_log: dict[str, Any], bias: dict[str, Any]
) -> dict[str, str]:
    """Every plot that has data; returns {plot key: file name}. Empty inputs get no plot (the page says so)."""
    plots: dict[str, str] = {}

    def add(key: str, fn, *args) -> None:
        name = f"{key}.png"
        fn(report_dir / name, *args)
        plots[key] = name

    if stats["by_relation"]:
        add(
            "qa_by_relation", _hbar, sorted_counts(stats["by_relation"]), "QA pairs per relation", "QA pairs", "#2171b5"
        )
    if stats["by_family"]:
        add(
            "qa_by_family",
            _hbar,
            sorted_counts(stats["by_family"]),
            "QA pairs per question family",
            "QA pairs",
            "#238b45",
        )
    if any(stats["by_steps"].values()):
        add(
            "qa_by_steps",
            _vbar,
            steps_counts(stats["by_steps"]),
            "QA pairs per step count",
            "reasoning steps",
            "QA pairs",
            "#fd8d3c",
        )
    if stats["by_source"]:
        add("qa_by_source", _hbar, sorted_counts(stats["by_source"]), "QA pairs per source", "QA pairs", "#807dba")
    if bias["points"]:
        add("answer_heatmap", _heatmap, stats["answer_heatmap"], bias)
    if any(stats["dropped"].values()):
        add("dropped_by_reason", _hbar, sorted_counts(stats["dropped"]), "Dropped units by reason", "units", "#cb181d")
    if run_log.get("stage_seconds"):
        add("time_per_stage", _stages, run_log["stage_seconds"])
    if run_log.get("units_per_s") is not None or run_log.get("qa_per_s") is not None:
        add("throughput", _throughput, run_log)
    return plots
