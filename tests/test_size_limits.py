"""Small modules with one job: modules at most 400 lines, functions at most 80 (walked from the AST of
refspatial_gen/). The test lists every offender outside the allow-list."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "refspatial_gen"
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80

# Every module and function is within the limits (issue #20); a new offender needs a reason here.
ALLOWED: set[str] = set()


def offenders() -> list[str]:
    out = []
    for path in sorted(PKG.rglob("*.py")):
        rel = str(path.relative_to(PKG))
        src = path.read_text()
        n = len(src.splitlines())
        if n > MAX_MODULE_LINES:
            out.append((rel, f"{rel}: {n} lines"))
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    out.append((f"{rel}:{node.name}", f"{rel}:{node.lineno} {node.name}: {length} lines"))
    return [msg for key, msg in out if key not in ALLOWED]


def test_modules_and_functions_within_size_limits() -> None:
    assert offenders() == []
