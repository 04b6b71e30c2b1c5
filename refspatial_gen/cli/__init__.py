"""`refspatial-gen` command line. Each command group lives in its own module with `register(subparsers)`.

No traceback ever reaches a user: a recipe or input error prints `file:line: message` / `path: message`
(exit 2), a run-level failure its one-line message, Ctrl-C / SIGTERM how to resume (exit 130 / 143), and
anything unforeseen one line plus the log file that holds the traceback (exit 1). REFSPATIAL_DEBUG=1
shows the traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path

from refspatial_gen import __version__
from refspatial_gen.core.errors import InputError, RecipeError, RecipeErrors, RunError, Terminated

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
    "refspatial_gen.cli.perception",
]
DEBUG_ENV = "REFSPATIAL_DEBUG"


def _on_sigterm(signum, frame) -> None:
    raise Terminated()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="refspatial-gen", description=__doc__.split("\n")[0])
    p.add_argument("--version", action="version", version=f"refspatial-gen {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return p


def _log_traceback(argv: list[str] | None) -> Path | None:
    """Write the current exception's traceback to a log file; its path, or None when that fails too."""
    try:
        fd, name = tempfile.mkstemp(prefix=f"refspatial-gen-{time.strftime('%Y%m%d-%H%M%S')}-", suffix=".log")
        with os.fdopen(fd, "w") as f:
            f.write(f"refspatial-gen {__version__}\nargv: {argv if argv is not None else sys.argv[1:]}\n\n")
            f.write(traceback.format_exc())
        return Path(name)
    except OSError:
        return None


def _say(msg: str) -> None:
    try:
        print(msg, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def run_command(args: argparse.Namespace, argv: list[str] | None) -> int:
    """Run one parsed command; every failure becomes a message and an exit status."""
    try:
        return int(args.func(args) or 0)
    except RecipeErrors as e:
        _say(str(e))
        return 2
    except (RecipeError, InputError) as e:
        _say(str(e))
        return 2
    except RunError as e:
        _say(f"refspatial-gen: {e.message}")
        return e.code
    except KeyboardInterrupt:
        _say("refspatial-gen: interrupted (Ctrl-C)")
        return 130
    except Terminated:
        _say("refspatial-gen: terminated (SIGTERM)")
        return 143
    except BrokenPipeError:  # output piped into `head` and closed: not an error of ours
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except MemoryError:
        _say("refspatial-gen: out of memory")
        return 1
    except Exception as e:  # the last line of defence: one line, the details in a log file
        if os.environ.get(DEBUG_ENV):
            raise
        log = _log_traceback(argv)
        where = f"; details in {log}" if log else ""
        if isinstance(e, OSError) and (e.filename or e.strerror):
            _say(f"refspatial-gen: {e.filename or ''}{': ' if e.filename else ''}{e.strerror or e}{where}")
        else:
            _say(f"refspatial-gen: internal error: {type(e).__name__}: {str(e)[:300]}{where}")
        return 1


def main(argv: list[str] | None = None) -> int:
    previous = None
    if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
        try:
            previous = signal.signal(signal.SIGTERM, _on_sigterm)
        except ValueError:  # not the main thread (embedded use): leave signals alone
            previous = None
    try:
        try:
            args = build_parser().parse_args(argv)
        except KeyboardInterrupt:
            return 130
        except Terminated:
            return 143
        return run_command(args, argv)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
