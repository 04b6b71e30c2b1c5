"""Annotation labels that do not say what their box or mask is (truth/data/unreliable_labels.yaml).

Why: SUN RGB-D's "dresser mirror" box covers the dresser under the mirror, so the answer point of "the
dresser mirror" may lie on drawers (audit round 2). Sources keep such objects as distractors only.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

DATA = Path(__file__).parent / "data"
UNRELIABLE = "unreliable_label"  # the reason sources record (provenance["distractor_only"])


@dataclass(frozen=True)
class Doubt:
    reason: str  # why the label does not name what its box holds
    could_be: tuple[str, ...]  # what a person may call the thing in the mask

    def provenance(self, measured_visible_fraction: float) -> dict[str, Any]:
        """What a source records on such an object (its visible_fraction is set to 0: a distractor only)."""
        return {
            "distractor_only": UNRELIABLE,
            "unreliable_label": self.reason,
            "label_could_be": list(self.could_be),
            "measured_visible_fraction": round(float(measured_visible_fraction), 4),
        }


def normalise(label: str) -> str:
    return " ".join(str(label).strip().lower().replace("_", " ").split())


@lru_cache(maxsize=1)
def _unreliable() -> dict[str, Doubt]:
    """label -> why its box is not the thing; every entry must cite a known source."""
    import yaml

    with open(DATA / "unreliable_labels.yaml", encoding="utf-8") as f:
        raw = yaml.safe_load(f) or {}
    sources = raw.get("sources") or {}
    out: dict[str, Doubt] = {}
    for name, e in (raw.get("labels") or {}).items():
        src = list((e or {}).get("src") or [])
        if not (e or {}).get("reason") or not src or any(s not in sources for s in src):
            raise ValueError(f"unreliable_labels.yaml: {name}: needs a reason and known sources, got {e!r}")
        could = tuple(normalise(c) for c in (e.get("could_be") or []))
        out[normalise(name)] = Doubt(str(e["reason"]), could)
    return out


def unreliable_label(label: str) -> Doubt | None:
    """Why the annotation label `label` does not name what its box holds (and what it may hold), or None."""
    return _unreliable().get(normalise(label))
