"""The ``dronetrack`` command line: parse, build, call, report, exit code.

Errors the user can fix (bad names, files, values) print one ``error:`` line
and exit with code 2; Ctrl-C prints one ``interrupted`` line and exits with 130.
"""

from __future__ import annotations

import sys

import typer

from dronetrack.cli import (  # noqa: F401  (they register on app)
    bench,
    compare,
    emulate,
    live,
    recordings,
    sapient,
    simulate,
    sweep,
)
from dronetrack.cli.app import INTERRUPTED, RunInterruptedError, app
from dronetrack.cli.output import console_logging, err_console
from dronetrack.errors import DronetrackError

__all__ = ["main", "run"]


def run(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv``; return the exit code.

    Ctrl-C ends a running loop after its current frame (``dronetrack.interrupt``); the
    command keeps what it had done and exits with 130 after one ``interrupted`` line.
    """
    from dronetrack.interrupt import handling_sigint

    if argv is not None and not argv:
        argv = ["--help"]  # bare `dronetrack`: the help, and no error
    command = typer.main.get_command(app)
    try:
        with handling_sigint(), console_logging():
            result = command.main(args=argv, prog_name="dronetrack", standalone_mode=False)
    except typer.Exit as stop:
        return int(stop.exit_code)
    except RunInterruptedError as stop:
        return _interrupted(str(stop))
    except (typer.Abort, KeyboardInterrupt):
        return _interrupted()
    except typer.TyperException as err:  # usage errors: unknown option, missing argument, ...
        describe = getattr(err, "format_message", None)
        message = describe() if callable(describe) else str(err)
        return _error(message)
    except (DronetrackError, OSError) as err:
        return _error(str(err))
    except SystemError as err:  # Ctrl-C inside numba's compiler surfaces as SystemError
        if _caused_by_interrupt(err):
            return _interrupted()
        raise
    if result == INTERRUPTED:  # typer turns a KeyboardInterrupt into this exit code
        return _interrupted()
    return int(result) if isinstance(result, int) else 0


def _error(message: str) -> int:
    err_console.print(f"error: {message}", markup=False, highlight=False, soft_wrap=True)
    return 2


def _interrupted(note: str = "") -> int:
    err_console.print(f"interrupted{note}", markup=False, highlight=False, soft_wrap=True)
    return INTERRUPTED


def _caused_by_interrupt(err: BaseException) -> bool:
    seen: set[int] = set()
    cause: BaseException | None = err
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


def main() -> None:
    """Console-script entry point."""
    from dronetrack.allocator import tune_allocator
    from dronetrack.interrupt import exit_on_sigint

    tune_allocator()
    # A Ctrl-C outside the command's own handling (before it, or after it ends and
    # before the line below) exits as interrupted, rather than dying of the signal
    exit_on_sigint(INTERRUPTED)
    code = run(sys.argv[1:])
    exit_on_sigint(code)  # a Ctrl-C while the interpreter shuts down ends it at once
    sys.exit(code)
