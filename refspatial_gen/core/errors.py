"""Error types with meaning for the run: a dropped unit is counted by reason, a recipe error stops the run."""

from __future__ import annotations


class DropUnit(Exception):
    """Raised by any stage when one input (scene, frame, image) is unusable.

    `reason` is a short stable code (e.g. "physics_not_settled", "depth_nan", "image_undecodable") that the
    run report counts; `detail` is free text for the run log. The run drops the unit and goes on.
    """

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail


class RecipeError(Exception):
    """A problem in a recipe or template file, reported as `file:line: message` before any work starts."""

    def __init__(self, file: str, line: int | None, message: str) -> None:
        self.file, self.line, self.message = str(file), line, message
        super().__init__(f"{self.file}:{line if line is not None else 0}: {message}")


class RecipeErrors(Exception):
    """Several recipe errors at once (lint reports them all)."""

    def __init__(self, errors: list[RecipeError]) -> None:
        self.errors = errors
        super().__init__("\n".join(str(e) for e in errors))
