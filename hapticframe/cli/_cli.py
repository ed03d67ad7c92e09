"""The ``hapticframe`` command line.

Kept import-light: each command imports what it needs when it runs, so ``--help``,
``plugins``, ``validate`` and ``schema`` never load torch, scikit-learn or device libraries.
Exit status: 0 success, 1 failure while running, 2 bad input or usage, 130 or 143 a run
interrupted by SIGINT (Ctrl-C) or SIGTERM. Output cut short by a closed pipe
(``hapticframe schema | head``) is not an error.

The library logs through :mod:`logging` and prints nothing itself; :func:`main` sends the
``hapticframe`` logger's warnings (and, for the duration of the command, Python warnings)
to stderr as one line each.
"""

from __future__ import annotations

import argparse
import logging
import warnings
from collections.abc import Sequence
from typing import Any

from hapticframe.cli import (
    _bench,
    _check,
    _import,
    _import_bag,
    _plugins,
    _recover,
    _replay,
    _report,
    _run,
    _schema,
    _sweep,
    _train,
    _validate,
    _view,
)
from hapticframe.cli._common import (
    closed_pipe,
    err,
    out,
)

__all__ = ["COMMANDS", "main"]

#: The subcommands in the order --help lists them; each module's ``register`` adds its own.
COMMANDS = (
    _plugins,
    _validate,
    _schema,
    _check,
    _run,
    _recover,
    _import_bag,
    _import,
    _replay,
    _view,
    _report,
    _train,
    _bench,
    _sweep,
)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hapticframe",
        description="Find objects buried in granular media by touch: assemble and run "
        "experiments from plugins.",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    for command in COMMANDS:
        command.register(sub)
    return parser


def _one_line_warning(message: Any, category: Any, filename: str, lineno: int, file: Any = None,
                      line: Any = None) -> None:
    err(f"warning: {message}")


class _StderrHandler(logging.Handler):
    """The library's log records as ``warning: message`` lines on the current stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            err(f"{record.levelname.lower()}: {record.getMessage()}")
        except Exception:  # logging's own policy for a failing handler
            self.handleError(record)


def _configure_logging(debug: bool) -> logging.Handler:
    handler = _StderrHandler(logging.DEBUG if debug else logging.WARNING)
    logger = logging.getLogger("hapticframe")
    logger.addHandler(handler)
    if debug:
        logger.setLevel(logging.DEBUG)
    return handler


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``hapticframe`` and ``python -m hapticframe``."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.version:
        from hapticframe._version import __version__

        out(f"hapticframe {__version__}")
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    handler = _configure_logging(args.debug)
    try:
        # One-line warnings for this command only: catch_warnings restores the process's
        # own showwarning when the command returns.
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return _dispatch(args)
    except BrokenPipeError:
        return closed_pipe()
    finally:
        logging.getLogger("hapticframe").removeHandler(handler)


def _dispatch(args: argparse.Namespace) -> int:
    from hapticframe._errors import HapticframeError, RunInterrupted

    try:
        return int(args.func(args))
    except BrokenPipeError:
        raise
    except RunInterrupted as exc:
        err(f"interrupted ({exc.signal_name}); the run's run.json records it")
        return exc.exit_code
    except HapticframeError as exc:
        if args.debug:
            raise
        err(f"error: {exc}" if "\n" not in str(exc) else str(exc))
        _hints(exc)
        return exc.exit_code
    except KeyboardInterrupt:
        err("interrupted")
        return 130
    except Exception as exc:  # a bug: one line, the traceback with --debug
        if args.debug:
            raise
        err(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug for the traceback)")
        return 1


def _hints(exc: BaseException) -> None:
    try:
        from hapticframe._manager import get_plugin_manager

        for hints in get_plugin_manager().hook.hapticframe_error_hints(error=exc):
            for hint in hints or ():
                err(f"hint: {hint}")
    except Exception:  # hints must never hide the error itself
        pass

