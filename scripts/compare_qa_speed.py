"""QA speed of two checkouts on the same machine, alternating runs (fair under a varying load).

Each run is a fresh process with PYTHONPATH=<checkout> measuring `qa.bench.qa_throughput` (cached toy
graphs, all checks on, per-sample index rebuilt: the `make bench` QA figure). Prints each run and the
medians. Usage: python scripts/compare_qa_speed.py OLD_CHECKOUT NEW_CHECKOUT [ROUNDS] [SECONDS]
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys

CODE = ("import json; from refspatial_gen.qa.bench import qa_throughput, toy_graphs; p = toy_graphs(); "
        "qa_throughput(p, seconds=0.5); print(json.dumps(qa_throughput(p, seconds={s})))")


def run(checkout: str, seconds: float) -> float:
    env = {**os.environ, "PYTHONPATH": checkout}
    out = subprocess.run([sys.executable, "-c", CODE.format(s=seconds)], env=env, cwd=checkout, check=True,
                         capture_output=True, text=True).stdout
    return float(json.loads(out.strip().splitlines()[-1])["qa_per_second_per_core"])


def main() -> None:
    old, new = sys.argv[1], sys.argv[2]
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 6
    seconds = float(sys.argv[4]) if len(sys.argv) > 4 else 3.0
    res: dict[str, list[float]] = {"old": [], "new": []}
    for k in range(rounds):
        order = [("old", old), ("new", new)] if k % 2 == 0 else [("new", new), ("old", old)]
        for name, path in order:
            res[name].append(run(path, seconds))
            print(f"round {k + 1} {name}: {res[name][-1]:.0f} QA pairs/s per core", flush=True)
    mo, mn = statistics.median(res["old"]), statistics.median(res["new"])
    paired = statistics.median(n / o for o, n in zip(res["old"], res["new"]))  # each round's pair ran back to back
    print(json.dumps({"old_median": mo, "new_median": mn, "ratio_of_medians": round(mn / mo, 4),
                      "median_paired_ratio": round(paired, 4), "old": res["old"], "new": res["new"]}, indent=1))


if __name__ == "__main__":
    main()
