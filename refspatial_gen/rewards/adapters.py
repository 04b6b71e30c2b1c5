"""The rewards with the call signatures of TRL's `GRPOTrainer` and of verl's reward managers.

TRL (checked against trl 1.16.0, `GRPOTrainer._calculate_rewards`): each function in `reward_funcs` is
called as `f(prompts=[...], completions=[...], completion_ids=[...], **columns, trainer_state=...,
log_extra=..., log_metric=...)`, where every other dataset column arrives as a list with one entry per
completion and `completions` are strings (standard data) or `[{"role": "assistant", "content": str}]`
(conversational data). It returns one float (or None: "does not apply") per completion. These functions
read the gold JSON string from the RFT export's `reward_model` column (`{"style", "ground_truth"}`) or
from a plain `ground_truth` column:

    from refspatial_gen.rewards.adapters import trl_reward_funcs
    trainer = GRPOTrainer(model=..., reward_funcs=trl_reward_funcs(),
                          args=GRPOConfig(reward_weights=[1, 1, .25, .25]), ...)

verl (checked against volcengine/verl, `NaiveRewardManager` / the reward-loop managers and
`BatchRewardManager`): a custom reward function is called as `compute_score(data_source=...,
solution_str=..., ground_truth=..., extra_info=...)` and may return a float or a dict with "score"
(other keys are logged); the batch manager calls `compute_score(data_sources=..., solution_strs=...,
ground_truths=..., extra_infos=...)` and expects a list. Point verl's `custom_reward_function.path` at
this file and `name` at `compute_score` (or `compute_score_batch` with `reward_model.reward_manager=batch`).
`extra_info` may carry `variant` ("paper" | "region") and `point_convention`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from refspatial_gen.rewards.gold import coerce_gold
from refspatial_gen.rewards.reward import (
    WEIGHTS,
    accuracy_reward,
    format_reward,
    process_accuracy_reward,
    process_format_reward,
    score,
)


def completion_text(completion: Any) -> str:
    """TRL completions are a string or a list of chat messages (the assistant turn's content)."""
    if isinstance(completion, str):
        return completion
    if isinstance(completion, list):
        parts = []
        for msg in completion:
            c = msg.get("content") if isinstance(msg, dict) else msg
            if isinstance(c, list):  # multimodal content blocks
                c = "".join(b.get("text", "") for b in c if isinstance(b, dict))
            parts.append(str(c or ""))
        return "".join(parts)
    raise TypeError(f"completion of type {type(completion).__name__} (expected str or a list of messages)")


def _trl(name: str, fn: Callable[[str, Any], float | None]) -> Callable[..., list[float | None]]:
    def reward(
        prompts=None, completions=None, completion_ids=None, ground_truth=None, reward_model=None, **kwargs
    ) -> list[float | None]:
        if ground_truth is None and reward_model is not None:  # the RFT export's verl-style column
            ground_truth = [r["ground_truth"] for r in reward_model]
        if completions is None or ground_truth is None:
            raise ValueError(
                f"{name}: needs `completions` and a `reward_model` or `ground_truth` column (export --format rft)"
            )
        if len(ground_truth) != len(completions):
            raise ValueError(f"{name}: {len(completions)} completions but {len(ground_truth)} ground truths")
        return [fn(completion_text(c), coerce_gold(g)) for c, g in zip(completions, ground_truth)]

    reward.__name__ = reward.__qualname__ = name  # TRL logs each function under its name
    reward.__doc__ = f"TRL reward function `{name}` (see refspatial_gen.rewards.reward)."
    return reward


format_reward_trl = _trl("format_reward", format_reward)
point_reward_trl = _trl("point_reward", lambda t, g: accuracy_reward(t, g, "paper"))
region_reward_trl = _trl("region_reward", lambda t, g: accuracy_reward(t, g, "region"))
process_format_reward_trl = _trl("process_format_reward", process_format_reward)
process_accuracy_reward_trl = _trl("process_accuracy_reward", process_accuracy_reward)


def trl_reward_funcs(variant: str = "paper") -> list[Callable[..., list[float | None]]]:
    """The four rewards in the paper's order; use `GRPOConfig(reward_weights=trl_reward_weights())`."""
    acc = point_reward_trl if variant == "paper" else region_reward_trl
    return [format_reward_trl, acc, process_format_reward_trl, process_accuracy_reward_trl]


def trl_reward_weights() -> list[float]:
    return [WEIGHTS["format"], WEIGHTS["accuracy"], WEIGHTS["process_format"], WEIGHTS["process_accuracy"]]


def compute_score(
    data_source: str | None = None,
    solution_str: str = "",
    ground_truth: Any = None,
    extra_info: dict | None = None,
    **kwargs,
) -> dict:
    """verl: {"score": weighted reward over the components that apply, divided by its maximum, plus each
    component (n/a components as -1, since verl aggregates numbers) and "success"}."""
    if ground_truth is None:
        raise ValueError("compute_score: ground_truth is missing (reward_model.ground_truth of the RFT export)")
    info = extra_info if isinstance(extra_info, dict) else {}
    s = score(
        solution_str or "",
        coerce_gold(ground_truth),
        variant=info.get("variant", "paper"),
        point_convention=info.get("point_convention", "auto"),
    )
    out = {"score": float(s["reward_norm"]), "success": float(s["success"])}
    for k in WEIGHTS:
        out[k] = -1.0 if s[k] is None else float(s[k])
    return out


def compute_score_batch(
    data_sources=None, solution_strs=None, ground_truths=None, extra_infos=None, **kwargs
) -> list[dict]:
    """verl's BatchRewardManager convention: lists in, one result per item out."""
    n = len(solution_strs or [])
    data_sources = list(data_sources) if data_sources is not None else [None] * n
    extra_infos = list(extra_infos) if extra_infos is not None else [None] * n
    return [
        compute_score(ds, s, gt, ei) for ds, s, gt, ei in zip(data_sources, solution_strs, ground_truths, extra_infos)
    ]
