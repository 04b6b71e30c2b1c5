"""Rewards for reinforcement fine-tuning and the scoring `refspatial-gen eval` uses (see docs/eval.md).

- `parse`: what models write (points in four conventions, choice letters, numbers with units, traces).
- `gold`: the ground truth a reward reads for one QA pair (`Gold`, `build_gold`).
- `reward`: the reward functions (RoboRefer's outcome/point/process rewards and a region variant), `score`.
- `adapters`: the same with TRL's `GRPOTrainer` and verl's `compute_score` signatures.
- `regions`: the image mask of a free-space region.
"""

from refspatial_gen.rewards.gold import Gold, build_gold, coerce_gold, gold_text
from refspatial_gen.rewards.reward import (
    accuracy_reward,
    format_reward,
    point_reward,
    process_accuracy_reward,
    process_format_reward,
    region_reward,
    score,
    success,
)

__all__ = [
    "Gold",
    "build_gold",
    "coerce_gold",
    "gold_text",
    "accuracy_reward",
    "format_reward",
    "point_reward",
    "process_accuracy_reward",
    "process_format_reward",
    "region_reward",
    "score",
    "success",
]
