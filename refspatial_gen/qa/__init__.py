"""Template engine: YAML templates -> typed programs -> checked QA pairs with reasoning traces.

Public API:
- `load_qa_config(section, recipe_file, lines) -> QAConfig` (the recipe's `qa:` section; compiles templates)
- `generate_qa(frames, graphs, rng, config) -> list[QAPair]`
- `verify_sample(sample) -> list[dict]` (independent re-check; empty list = all QA pairs pass)
- `QA_FIELDS` (schema of the `qa:` section)
"""

from __future__ import annotations

from typing import Any

from refspatial_gen.core.model import Sample
from refspatial_gen.qa.config import QA_FIELDS, QAConfig, load_qa_config
from refspatial_gen.qa.generate import generate_qa


def verify_sample(sample: Sample) -> list[dict[str, Any]]:  # imported lazily: the verifier has its own path
    from refspatial_gen.qa.verify import verify_sample as _v

    return _v(sample)


__all__ = ["QA_FIELDS", "QAConfig", "load_qa_config", "generate_qa", "verify_sample"]
