"""The run report's figures from its input dicts: checks of `stats`, derived figures (drop rate, answer
location bias, silent families) and the plain-text summary `refspatial-gen stats` prints (run/report.py)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

HEATMAP_BINS = 20

STAGES = ("load", "graph", "qa", "write")


_REQUIRED = {
    "samples": int,
    "qa_pairs": int,
    "by_relation": dict,
    "by_family": dict,
    "by_steps": dict,
    "by_source": dict,
    "dropped": dict,
    "answer_heatmap": list,
}


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
    return {
        "points": total,
        "mean": [r4(mx), r4(my)],
        "std": [r4(sx), r4(sy)],
        "thirds": [[r4(v / total) for v in row] for row in thirds],
        "entropy": r4(ent),
    }


def sorted_counts(d: dict[str, int]) -> list[tuple[str, int]]:
    """Largest first, ties by name: readable and stable."""
    return sorted(((str(k), int(v)) for k, v in d.items()), key=lambda kv: (-kv[1], kv[0]))


def steps_counts(d: dict[str, int]) -> list[tuple[str, int]]:
    keys = sorted(
        set(d) | {str(i) for i in range(1, 6)},
        key=lambda k: (not str(k).isdigit(), int(k) if str(k).isdigit() else 0, str(k)),
    )
    return [(str(k), int(d.get(k, 0))) for k in keys]


def silent_families(stats: dict[str, Any], recipe_info: dict[str, Any] | None) -> list[str]:
    """Families the recipe asks for (weight > 0) that produced no QA pair in the whole run.

    Why: a family that never fires is invisible in a table of counts; e.g. `identify` needs a support
    surface, which plain photos lack, so an image recipe that lists it silently gets none."""
    fams = (recipe_info or {}).get("families") or {}
    return sorted(f for f, w in fams.items() if float(w or 0) > 0 and not stats["by_family"].get(f))


def derived(
    stats: dict[str, Any], run_log: dict[str, Any], recipe_info: dict[str, Any] | None = None
) -> dict[str, Any]:
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


# ---------------------------------------------------------------------------------------------- text
def fmt_rate(v: Any, unit: str = "/s") -> str:
    return "-" if v is None else f"{float(v):,.2f}{unit}"


def summary_lines(
    stats: dict[str, Any], run_log: dict[str, Any] | None = None, recipe_info: dict[str, Any] | None = None
) -> list[str]:
    """The header figures as plain text lines (what `stats` prints and the page's summary shows)."""
    run_log = run_log or {}
    d = derived(stats, run_log, recipe_info)
    lines = [
        f"samples     {stats['samples']:,}",
        f"QA pairs    {stats['qa_pairs']:,}"
        + (f"  ({d['qa_per_sample']} per sample)" if d["qa_per_sample"] is not None else ""),
    ]
    drop = f"dropped     {d['dropped_total']:,}"
    if d["drop_rate"] is not None:
        drop += f" of {stats.get('units', 0):,} units ({100 * d['drop_rate']:.1f}%)"
    lines.append(drop)
    if run_log:
        lines.append(
            f"QA/s        {fmt_rate(run_log.get('qa_per_s'), '')}   units/s {fmt_rate(run_log.get('units_per_s'), '')}"
        )
        lines.append(
            f"wall time   {float(run_log.get('wall_seconds') or 0):,.1f} s on {run_log.get('workers', '?')} "
            f"worker(s), executor {run_log.get('executor', '?')}"
        )
    if d["silent_families"]:
        lines.append(f"warning     families that produced no QA pair: {', '.join(d['silent_families'])}")
    loc = d["answer_location"]
    if loc["points"]:
        lines.append(
            f"answers     mean point ({loc['mean'][0]:.3f}, {loc['mean'][1]:.3f}), "
            f"spread entropy {loc['entropy']:.2f} (1 = uniform)"
        )
    return lines
