"""Run report: figures derived correctly, files self-contained, bad stats refused, output deterministic."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from refspatial_gen.run.report import (
    check_stats,
    load_report,
    location_bias,
    summary_lines,
    write_report,
)

RUN_LOG = {"wall_seconds": 100.0, "stage_seconds": {"load": 40.0, "graph": 20.0, "qa": 30.0, "write": 10.0},
           "workers": 2, "executor": "local", "units_per_s": 1.1, "qa_per_s": 9.5, "peak_rss_mb_per_worker": 300.0,
           "started": "2025-01-01T00:00:00Z", "host": "h"}
RECIPE = {"name": "default", "recipe_hash": "abc123", "seed": 7, "code_version": "0.1.0"}


def _heat(points: list[tuple[float, float]]) -> list[list[int]]:
    hm = [[0] * 20 for _ in range(20)]
    for x, y in points:
        hm[min(19, int(y * 20))][min(19, int(x * 20))] += 1
    return hm


def make_stats(**over) -> dict:
    rng = np.random.default_rng(0)
    pts = [(float(x), float(y)) for x, y in rng.random((300, 2))]
    s = {"samples": 110, "qa_pairs": 950, "units": 120,
         "by_relation": {"left_of": 300, "behind": 120, "near": 55, "between": 40},
         "by_family": {"locate": 500, "choice": 300, "placement": 150},
         "by_steps": {"1": 400, "2": 300, "3": 150, "4": 70, "5": 30},
         "by_source": {"toy": 950}, "dropped": {"no_questions": 7, "invalid_frame": 3},
         "answer_heatmap": _heat(pts)}
    s.update(over)
    return s


def test_location_bias_extremes():
    one = location_bias(_heat([(0.81, 0.12)] * 50))  # every point in cell row 2, col 16
    assert one["points"] == 50 and one["entropy"] == 0.0
    assert one["mean"] == [round(16.5 / 20, 4), round(2.5 / 20, 4)] and one["std"] == [0.0, 0.0]
    assert one["thirds"][0][2] == 1.0 and sum(map(sum, one["thirds"])) == 1.0
    uni = location_bias([[3] * 20 for _ in range(20)])
    assert uni["entropy"] == 1.0 and uni["mean"] == [0.5, 0.5]
    assert abs(sum(map(sum, uni["thirds"])) - 1.0) < 1e-3 and uni["thirds"][1][1] == pytest.approx(36 / 400, abs=1e-4)
    assert location_bias([[0] * 20 for _ in range(20)])["mean"] is None
    # a left-heavy set has its mean on the left and a lower entropy than uniform
    left = location_bias(_heat([(0.05 + 0.1 * (i % 3), 0.05 * (i % 20)) for i in range(200)]))
    assert left["mean"][0] < 0.25 and left["entropy"] < 1.0 and sum(r[0] for r in left["thirds"]) == pytest.approx(1.0)


@pytest.mark.parametrize("bad, msg", [
    ({"samples": -1}, "negative"),
    ({"answer_heatmap": [[0] * 20] * 19}, "20x20"),
    ({"answer_heatmap": [[0] * 20] * 19 + [[0] * 19 + [-1]]}, "not a count"),
    ({"dropped": {"x": 1.5}}, "not a count"),
    ({"qa_pairs": "9"}, "should be int"),
])
def test_check_stats_refuses_malformed(bad, msg):
    with pytest.raises(ValueError, match=msg):
        check_stats(make_stats(**bad))
    s = make_stats()
    del s["by_family"]
    with pytest.raises(ValueError, match="missing 'by_family'"):
        check_stats(s)


def test_write_report_files_summary_and_links(tmp_path):
    stats = make_stats()
    page = write_report(tmp_path, stats, RUN_LOG, {**RECIPE, "name": "<script>alert(1)</script>"})
    rd = tmp_path / "report"
    assert page == rd / "report.html"
    rep = json.loads((rd / "report.json").read_text())
    assert rep["stats"] == stats and rep["run_log"] == RUN_LOG
    assert rep["derived"]["dropped_total"] == 10 and rep["derived"]["drop_rate"] == round(10 / 120, 4)
    assert rep["derived"]["answer_location"]["points"] == 300
    assert set(rep["plots"]) == {"qa_by_relation", "qa_by_family", "qa_by_steps", "qa_by_source", "answer_heatmap",
                                 "dropped_by_reason", "time_per_stage", "throughput"}
    html = page.read_text()
    srcs = re.findall(r'<img src="([^"]+)"', html)
    assert sorted(srcs) == sorted(rep["plots"].values())
    for s in srcs:  # relative links to PNGs beside the page
        assert "/" not in s and (rd / s).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "file://" not in html and str(tmp_path) not in html and "<link" not in html and "<script" not in html
    assert "&lt;script&gt;" in html
    # header summary: samples, QA pairs, dropped, QA/s
    head = html[html.index("<header>") : html.index("</header>")]
    for text in ("110", "950", "10 (8.3%)", "9.50", "samples", "QA pairs", "dropped", "QA / s"):
        assert text in head
    assert load_report(tmp_path)["derived"] == rep["derived"]


def test_plot_sizes_follow_the_data(tmp_path):
    from PIL import Image

    few = write_report(tmp_path / "a", make_stats(), RUN_LOG, RECIPE).parent
    many = {f"rel_{i:02d}": i + 1 for i in range(31)}
    lots = write_report(tmp_path / "b", make_stats(by_relation=many), RUN_LOG, RECIPE).parent
    h_few = Image.open(few / "qa_by_relation.png").size[1]
    h_many = Image.open(lots / "qa_by_relation.png").size[1]
    assert h_many > 2 * h_few  # one readable row per relation
    assert (few / "qa_by_steps.png").read_bytes() == (lots / "qa_by_steps.png").read_bytes()


def test_empty_run_still_reports(tmp_path):
    stats = make_stats(samples=0, qa_pairs=0, by_relation={}, by_family={}, by_steps={}, by_source={}, dropped={},
                       answer_heatmap=[[0] * 20 for _ in range(20)])
    page = write_report(tmp_path, stats, {}, {})
    html = page.read_text()
    assert "No unit was dropped." in html and "No point answers." in html and "<img" not in html
    assert json.loads((tmp_path / "report" / "report.json").read_text())["plots"] == {}
    assert summary_lines(stats)[0].split() == ["samples", "0"]


def test_rerun_replaces_stale_plots_and_is_deterministic(tmp_path):
    write_report(tmp_path, make_stats(), RUN_LOG, RECIPE)
    first = {p.name: p.read_bytes() for p in (tmp_path / "report").iterdir()}
    write_report(tmp_path, make_stats(dropped={}), RUN_LOG, RECIPE)
    assert not (tmp_path / "report" / "dropped_by_reason.png").exists()
    write_report(tmp_path, make_stats(), RUN_LOG, RECIPE)
    again = {p.name: p.read_bytes() for p in (tmp_path / "report").iterdir()}
    assert first == again  # same inputs -> same bytes (plots carry no date or version stamp)


def test_summary_lines_for_the_stats_command():
    lines = summary_lines(make_stats(), RUN_LOG)
    text = "\n".join(lines)
    assert "samples     110" in text and "QA pairs    950" in text and "(8.636 per sample)" in text
    assert "dropped     10 of 120 units (8.3%)" in text and "QA/s        9.50" in text
    assert "2 worker(s), executor local" in text and "mean point" in text


def test_report_from_the_run_stats_of_real_samples(tmp_path, toy_frame):
    """The report consumes what run/stats.py aggregates: every answer point lands in the heat map."""
    stats_mod = pytest.importorskip("refspatial_gen.run.stats")
    from refspatial_gen.core.mask import answer_pixel, normalise_point
    from refspatial_gen.core.model import QAPair, Sample, SceneGraph

    qas = []
    for o in toy_frame.objects:
        p = normalise_point(*answer_pixel(o.mask.decode()), 320, 240)
        qas.append(QAPair(f"q{o.id}", "locate", "t", f"Point to object {o.id}.", str(p),
                          {"kind": "points", "points": [list(p)]}, ["left_of"], 1 + o.id % 3, [toy_frame.frame_id],
                          (320, 240), targets=[o.id]))
    stats = stats_mod.empty_stats()
    stats_mod.add_sample(stats, Sample("s", [toy_frame], [SceneGraph(toy_frame.frame_id, [])], qas), "toy")
    stats_mod.add_drop(stats, "no_questions")
    stats["units"] = 2
    write_report(tmp_path, stats, RUN_LOG, RECIPE)
    rep = load_report(tmp_path)
    assert rep["derived"]["answer_location"]["points"] == len(qas)
    assert rep["derived"]["drop_rate"] == 0.5
    mean_x = np.mean([q.answer_struct["points"][0][0] for q in qas])
    assert abs(rep["derived"]["answer_location"]["mean"][0] - mean_x) <= 0.025  # within half a cell


def test_internal_errors_are_flagged_and_escaped(tmp_path):
    log = {**RUN_LOG, "errors": ["Traceback ...\nValueError: bad <b>input</b>"] * 23, "groups_run": 4}
    html = write_report(tmp_path, make_stats(), log, {"recipe": "toy.yaml", "sources": [{"kind": "toy", "weight": 1.0}]}).read_text()
    head = html[html.index("<header>") : html.index("</header>")]
    assert "internal errors" in head and ">23<" in head
    assert "Internal errors (23)" in html and html.count("<pre>") == 20 and "3 more in run_log.json" in html
    assert "<b>input</b>" not in html and "&lt;b&gt;input&lt;/b&gt;" in html
    assert "refspatial-gen run report: toy.yaml" in html and '{&quot;kind&quot;: &quot;toy&quot;' in html


def test_truth_counts_from_frames_graphs_and_sample_are_summed_merged_and_shown(tmp_path):
    """Every truth check reports through one convention (frame / graph / sample meta); the run sums them."""
    from refspatial_gen.core.model import Sample
    from refspatial_gen.run import stats as S
    from tests.helpers.scenes import toy_scenes

    (f1, g1), (f2, g2) = toy_scenes([1, 2], 4)
    f1.meta["truth"] = {"implausible_size": 2}
    g1.meta["truth"] = {"below_visibility_floor": 1}
    g2.meta["truth"] = {"below_visibility_floor": 3}
    sample = Sample("s0", [f1, f2], [g1, g2], [], meta={"truth": {"colour_uncertain": 1}})
    assert S.truth_counts(sample) == {"implausible_size": 2, "below_visibility_floor": 4, "colour_uncertain": 1}
    a, b = S.empty_stats(), S.empty_stats()
    S.add_sample(a, sample, "toy")
    S.add_sample(b, sample, "toy")
    merged = S.merge(a, b)
    assert merged["truth"] == {"below_visibility_floor": 8, "colour_uncertain": 2, "implausible_size": 4}
    stats = make_stats(truth=merged["truth"])
    page = write_report(tmp_path, stats, RUN_LOG, RECIPE).read_text()
    assert "below_visibility_floor" in page and "Truth checks" in page


def test_a_family_the_recipe_asks_for_that_never_fires_is_named_in_the_report(tmp_path):
    """The image recipe's identify family never fired (it needs a support surface photos lack) and nothing
    said so: a zero count is invisible in a table of what was produced."""
    from refspatial_gen.run.report import silent_families

    recipe = {**RECIPE, "families": {"locate": 1.0, "choice": 1.0, "identify": 1.0, "multiview": 0.0}}
    stats = make_stats()
    assert silent_families(stats, recipe) == ["identify"]  # multiview has weight 0: not asked for
    page = write_report(tmp_path, stats, RUN_LOG, recipe).read_text()
    assert "Families that produced nothing" in page and "<b>identify</b>" in page
    assert any("identify" in line for line in summary_lines(stats, RUN_LOG, recipe))
    assert silent_families(stats, RECIPE) == []
