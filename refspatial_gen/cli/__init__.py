"""`refspatial-gen` command line. Each command group lives in its own module with `register(subparsers)`."""

from __future__ import annotations

import argparse
import importlib
import sys

from refspatial_gen import __version__
from refspatial_gen.core.errors import RecipeError, RecipeErrors

# Modules that add sub-commands: each defines `register(subparsers) -> None` and sets `func` on its parsers.
# The CLI is the layer above the stages: stage packages never import it.
COMMAND_MODULES = [
    "refspatial_gen.cli.preview",
    "refspatial_gen.cli.generate",
    "refspatial_gen.cli.data",
    "refspatial_gen.cli.relations",
    "refspatial_gen.cli.sim",
    "refspatial_gen.cli.assets",
    "refspatial_gen.cli.verify",
    "refspatial_gen.cli.eval",
    "refspatial_gen.cli.audit",
    "refspatial_gen.cli.rewrite",
]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="refspatial-gen", description=__doc__)
    p.add_argument("--version", action="version", version=f"refspatial-gen {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        rc = args.func(args)
    except (RecipeError, RecipeErrors) as e:
        print(str(e), file=sys.stderr)
        return 2
    return int(rc or 0)


if __name__ == "__main__":
    sys.exit(main())
