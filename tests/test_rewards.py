"""Reward functions on hand-made ground truths, and the TRL / verl call conventions."""

import json
import math

import numpy as np
import pytest

from refspatial_gen.core.mask import RLE
from refspatial_gen.rewards import adapters
from refspatial_gen.rewards.gold import Gold, coerce_gold
from refspatial_gen.rewards.reward import (accuracy_reward, format_reward, point_reward, process_accuracy_reward,
                                           process_format_reward, region_reward, score, step_correct, success)

W, H = 640, 480


def _point_gold(reasoning=True) -> Gold:
    """A 20x20 px target at (300..319, 200..219); gold point its centre; two key steps."""
    m = np.zeros((H, W), bool)
    m[200:220, 300:320] = True
    keys = [{"type": "Position", "phrase": "the mug", "value": [0.2, 0.3]},
            {"type": "Position", "phrase": "the red cup", "value": [310.5 / W, 210.5 / H]}]
    return Gold("q1", "points", (W, H), "[(0.485, 0.439)]", reasoning, keys if reasoning else [],
                points=[[310.5 / W, 210.5 / H]], mask=RLE.encode(m).to_json())


def _trace(points, steps):
    body = "\n".join(f"[{t}] [{p}]: {v}" for t, p, v in steps)
    pts = "[" + ", ".join(f"({x:.3f}, {y:.3f})" for x, y in points) + "]"
    return f"<think>{body}</think><answer>{pts}</answer>"


GOOD_STEPS = [("Position", "the mug", "(0.200, 0.300)"), ("Position", "the red cup", "(0.485, 0.439)")]


def test_gold_scores_full_and_moving_points_costs():
    g = _point_gold()
    gold = _trace([(310.5 / W, 210.5 / H)], GOOD_STEPS)
    s = score(gold, g)
    assert s["success"] == 1.0 and s["reward_norm"] == 1.0 and s["reward"] == pytest.approx(2.5)
    moved = _trace([((310.5 + 60) / W, 210.5 / H)], GOOD_STEPS)  # 60 px to the right: off the 20 px target
    assert accuracy_reward(moved, g, "paper") == 0.0 < accuracy_reward(gold, g, "paper") == 1.0
    assert region_reward(parse_px(moved), g) == 0.0  # 51 px from the mask's nearest pixel centre
    near = _trace([((310.5 + 30) / W, 210.5 / H)], GOOD_STEPS)  # 30 px: 21 px off the mask
    assert 0.0 < region_reward(parse_px(near), g) < 1.0
    assert success(moved, g) == 0.0 and success(near, g) == 0.0


def parse_px(text):
    from refspatial_gen.rewards.parse import parse_points

    return parse_points(text, W, H)


def test_region_reward_grades_by_distance_and_paper_reward_does_not():
    g = _point_gold()
    inside_far_from_centre = [(301.0, 201.0)]  # in the mask, 19 px (L1) from the gold point
    outside_10 = [(330.5, 210.5)]  # 10 px right of the mask (pixel centres 319.5 -> 330.5: 11 px)
    outside_40 = [(360.5, 210.5)]
    assert region_reward(inside_far_from_centre, g) == 1.0
    assert region_reward(outside_10, g) == pytest.approx(1 - 11 / 50)
    assert region_reward(outside_40, g) == pytest.approx(1 - 41 / 50)
    assert point_reward(outside_40, g) == 1.0  # 50 px L1 disc: pays for a point that misses the object
    assert region_reward([(600.0, 20.0)], g) == 0.0
    assert region_reward([(301.0, 201.0), (600.0, 20.0)], g) == pytest.approx(0.5)  # mean over points


def test_process_rewards_order_invariant_and_strict():
    g = _point_gold()
    pts = [(310.5 / W, 210.5 / H)]
    a = _trace(pts, GOOD_STEPS)
    b = _trace(pts, GOOD_STEPS[::-1])
    assert process_accuracy_reward(a, g) == process_accuracy_reward(b, g) == 1.0
    assert score(a, g) == score(b, g)
    half = _trace(pts, [GOOD_STEPS[0], ("Position", "the red cup", "(0.900, 0.900)")])
    assert process_accuracy_reward(half, g) == 0.5
    renamed = _trace(pts, [GOOD_STEPS[0], ("Position", "a cup", "(0.485, 0.439)")])
    assert process_accuracy_reward(renamed, g) == 0.5  # matched by phrase
    assert process_format_reward(a, g) == 1.0
    assert process_format_reward(a.replace("[Position] [the mug]", "Position the mug"), g) == 0.0
    assert process_format_reward("[(0.485, 0.439)]", g) == 0.0 and format_reward("[(0.485, 0.439)]", g) == 0.0
    swapped = _trace([(210.5 / H, 310.5 / W)], GOOD_STEPS)
    assert success(swapped, g) == 0.0 and accuracy_reward(swapped, g, "paper") == 0.0


def test_single_step_gold_without_trace():
    g = _point_gold(reasoning=False)
    s = score("[(0.485, 0.439)]", g)
    assert s["process_format"] is None and s["process_accuracy"] is None
    assert s["reward_norm"] == 1.0 and s["success"] == 1.0
    assert format_reward("<think>x</think><answer>[(0.485, 0.439)]</answer>", g) == 1.0
    assert format_reward("<answer>[(0.485, 0.439)]</answer>", g) == 0.0  # tags, but not the full structure
    assert format_reward("nothing", g) == 0.0


def test_step_checks():
    assert step_correct("Position", (0.5, 0.5), [0.5 + 49 / W, 0.5], (W, H))
    assert not step_correct("Position", (0.5, 0.5), [0.5 + 30 / W, 0.5 + 30 / H], (W, H))  # L1 60 px
    assert step_correct("Orientation", (1, 0, 0), [math.cos(0.6), math.sin(0.6), 0], (W, H))  # cos 0.825
    assert not step_correct("Orientation", (1, 0, 0), [math.cos(0.7), math.sin(0.7), 0], (W, H))  # cos 0.765
    assert step_correct("Size", (0.115,), [0.1], (W, H)) and not step_correct("Size", (0.12,), [0.1], (W, H))
    assert step_correct("Size", (0.2,), 0.2, (W, H))  # a bare scalar gold
    # the older 3-vector gold: a scalar is compared with the largest side, a 3-vector side by side
    assert step_correct("Size", (0.21,), [0.1, 0.15, 0.2], (W, H))
    assert not step_correct("Size", (0.15,), [0.1, 0.15, 0.2], (W, H))
    assert step_correct("Size", (0.1, 0.15, 0.2), [0.1, 0.15, 0.2], (W, H))
    assert not step_correct("Size", (0.1, 0.15, 0.3), [0.1, 0.15, 0.2], (W, H))


def test_choice_and_number_golds():
    c = Gold("c", "choice", (W, H), "(B)", options=["no", "yes"], letter="B")
    assert score("(B)", c)["success"] == 1.0 and score("yes", c)["success"] == 1.0 and score("(A)", c)["success"] == 0.0
    n = Gold("n", "number", (W, H), "35 centimeters", value=0.35, quantity="distance", unit="m")
    assert score("35 cm", n)["success"] == 1.0 and score("0.43 m", n)["success"] == 1.0
    assert score("0.45 m", n)["success"] == 0.0 and score("", n)["parsed"] is False
    r = Gold("r", "number", (W, H), "rotate left around 20.0 degrees", value=-math.radians(20), quantity="rotation_horizontal", unit="rad")
    assert score("rotate left around 10 degrees", r)["success"] == 1.0
    assert score("rotate right around 20 degrees", r)["success"] == 0.0  # the wrong way is 40 degrees off


def test_gold_json_round_trip_and_errors():
    g = _point_gold()
    again = coerce_gold(g.dumps())
    assert again.to_json() == g.to_json() and coerce_gold(g.to_json()).to_json() == g.to_json()
    with pytest.raises(ValueError):
        coerce_gold("{not json")
    with pytest.raises(ValueError):
        coerce_gold({"kind": "points"})
    with pytest.raises(ValueError):
        coerce_gold({**g.to_json(), "v": 99})


def test_trl_convention_standard_and_conversational():
    """Called exactly as trl 1.16 GRPOTrainer._calculate_rewards calls a custom function."""
    g = _point_gold().dumps()
    gold = _trace([(310.5 / W, 210.5 / H)], GOOD_STEPS)
    bad = "no idea"
    kwargs = {"reward_model": [{"style": "rule", "ground_truth": g}] * 2, "id": ["q1", "q1"],
              "trainer_state": object(), "log_extra": lambda *a: None, "log_metric": lambda *a: None}
    for completions in ([gold, bad], [[{"role": "assistant", "content": gold}], [{"role": "assistant", "content": bad}]]):
        outs = [f(prompts=["p", "p"], completions=completions, completion_ids=[[1], [2]], **kwargs)
                for f in adapters.trl_reward_funcs()]
        assert [o[0] for o in outs] == [1.0, 1.0, 1.0, 1.0]
        assert [o[1] for o in outs] == [0.0, 0.0, 0.0, 0.0]
    names = [f.__name__ for f in adapters.trl_reward_funcs("region")]
    assert names == ["format_reward", "region_reward", "process_format_reward", "process_accuracy_reward"]
    nogold = Gold("c", "choice", (W, H), "(B)", options=["no", "yes"], letter="B").dumps()
    assert adapters.process_format_reward_trl(completions=["(B)"], ground_truth=[nogold]) == [None]  # not applicable
    with pytest.raises(ValueError):
        adapters.format_reward_trl(prompts=["p"], completions=["x"])


def test_verl_convention_single_and_batch():
    """Called as verl's NaiveRewardManager / BatchRewardManager call a custom compute_score."""
    g = _point_gold().dumps()
    gold = _trace([(310.5 / W, 210.5 / H)], GOOD_STEPS)
    extra = {"qa_id": "q1", "num_turns": None, "rollout_reward_scores": {}}  # keys verl adds itself
    r = adapters.compute_score(data_source="refspatial-gen/locate", solution_str=gold, ground_truth=g, extra_info=extra)
    assert r["score"] == 1.0 and r["success"] == 1.0 and set(r) >= {"format", "accuracy", "process_format", "process_accuracy"}
    r2 = adapters.compute_score(data_source="x", solution_str="[(0.9, 0.9)]", ground_truth=g, extra_info={"variant": "paper"})
    assert r2["score"] == 0.0
    batch = adapters.compute_score_batch(data_sources=["a", "b"], solution_strs=[gold, "x"], ground_truths=[g, g],
                                         extra_infos=[{}, {}])
    assert [b["score"] for b in batch] == [1.0, 0.0]
    json.dumps(batch)  # plain numbers only
