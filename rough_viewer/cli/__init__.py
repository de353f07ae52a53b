"""Command-line front end: ``rough-viewer <command> ...``.

Each command lives in its own module of this package (``compute.py``,
``report.py``, ...; ``bias/`` has one module per subcommand) and exposes
``register(subparsers)``, which adds its parser and sets ``func`` (a callable taking
the parsed namespace and returning an exit status). Modules are found
automatically (those starting with ``_`` are helpers), so adding a command touches
no other file.

Problems the user can fix raise :class:`rough_viewer.vocabulary.InputError`, in the
science or here; :func:`main` is the one place that prints them as one line on
stderr and exits with status 2, never with a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence
from typing import NoReturn

from rough_viewer._version import __version__
from rough_viewer.vocabulary import InputError


class _Parser(argparse.ArgumentParser):
    """argparse parser whose usage errors are one line and exit 2."""

    def error(self, message: str) -> NoReturn:  # noqa: D401
        self.exit(2, f"{self.prog}: error: {message}\n")


def command_names() -> list[str]:
    """The commands: one module (or package) of this package each, found without
    importing them."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser with every command module found in this package, or with command
    ``only`` alone (a run imports the modules of its own command only)."""
    parser = _Parser(
        prog="rough-viewer",
        description="Surface roughness of scanned rock faces.",
    )
    parser.add_argument("--version", action="version", version=f"rough-viewer {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in command_names():
        if only is None or name == only:
            importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that the same clean-up runs (temporary output
    files, the reader's child process)."""


def _terminate(_signum: int, _frame: object) -> None:
    raise Terminated


#: Commands that read point clouds: a reader process is started with the command,
#: so its start-up overlaps the command's own (:func:`rough_viewer.io.sandbox.isolate.warm`).
READING_COMMANDS = frozenset({"compute", "report", "zones", "profile", "serve"})


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rough-viewer`` console script; returns the exit status."""
    import signal
    import threading

    argv = list(sys.argv[1:] if argv is None else argv)
    # the command is the first word that is not an option (the top level has only
    # --help and --version, which take no value); an unknown one gets the full list
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(command if command in command_names() else None)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        if args.command in READING_COMMANDS and getattr(args, "inputs", None):
            from rough_viewer.io.sandbox import isolate

            isolate.warm()
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"rough-viewer: error: {exc}", file=sys.stderr)
        return 2
    except Terminated:
        print("rough-viewer: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("rough-viewer: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # stdout closed early (e.g. piped into `head`): stop quietly, as Unix tools do
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
