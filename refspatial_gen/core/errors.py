"""Error types with meaning for the run: a dropped unit is counted by reason, a recipe error stops the run."""

from __future__ import annotations

from typing import Any


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


class InputError(Exception):
    """An input that prevents planning (missing/empty/unreadable input root, malformed top-level annotation
    file): the run stops before any work with `path: what is wrong` (exit 2)."""

    def __init__(self, path: str, message: str) -> None:
        self.path, self.message = str(path), message
        super().__init__(f"{self.path}: {message}")

    def __reduce__(self) -> tuple[type, tuple[str, str]]:  # picklable across worker processes
        return (InputError, (self.path, self.message))


class RunError(Exception):
    """A run-level failure with a clear one-line message and an exit status (output folder locked, a
    different run's output, a disk that is full). The CLI prints the message and exits with `code`."""

    def __init__(self, message: str, code: int = 1) -> None:
        self.message, self.code = message, code
        super().__init__(message)

    def __reduce__(self) -> tuple[type, tuple[Any, ...]]:
        return (RunError, (self.message, self.code))


class OutputIOError(RunError):
    """Writing an output file failed (disk full, I/O error): names the file, never a nested traceback."""

    def __init__(self, path: str, reason: str) -> None:
        self.path, self.reason = str(path), reason
        super().__init__(f"cannot write {self.path}: {reason}", 1)

    def __reduce__(self) -> tuple[type, tuple[Any, ...]]:
        return (OutputIOError, (self.path, self.reason))


class Terminated(BaseException):
    """SIGTERM, raised in the main thread the way KeyboardInterrupt is for SIGINT (a BaseException, so
    `except Exception` does not swallow it and every `finally` runs). The CLI installs the handler."""
