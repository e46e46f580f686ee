"""``plate-env`` command line: identify, probe, sweep, fit, calibrate, bench, build. ``--json`` on every command
prints one JSON document."""

from __future__ import annotations

import argparse
import os
import re
import sys
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol, TextIO

from plate_env.cli import bench, build, cache, calibrate, fit, identify, probe, sweep
from plate_env.cli.bench import strict_json
from plate_env.cli.fit import FIT_PROGRESS_ROWS
from plate_env.cli.options import MAX_FIT_ROWS, MAX_SWEEP_PROBES, TILELINK_MODELS_HELP, CliError
from plate_env.cli.sweep import parse_freqs

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers


class Command(Protocol):
    """A command's module: ``add_parser(sub)`` adds its subparser, ``run(args)`` runs it and returns the exit code."""

    def add_parser(self, sub: Subparsers) -> None: ...

    def run(self, args: argparse.Namespace) -> int: ...


#: Each command's module, in the order ``--help`` lists them.
COMMANDS: dict[str, Command] = {"probe": probe, "sweep": sweep, "identify": identify, "bench": bench, "fit": fit,
            "calibrate": calibrate, "cache": cache, "build": build}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="plate-env", description=__doc__)
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS.values():
        command.add_parser(sub)
    _set_formatter(parser)  # --help shows every default, in every subcommand (build's too)
    return parser


def _set_formatter(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = _DefaultsFormatter
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for p in action.choices.values():
                _set_formatter(p)


class _DefaultsFormatter(argparse.HelpFormatter):
    """Help that names each option's default (none shown for flags and options without one)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default  # by identity: a default of 0 or 0.0 is shown (0 == False hid --seed's, issue 40)
        shown = (action.option_strings and not (d is None or d is False or d is argparse.SUPPRESS or d == [])
                 and not isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)))
        if shown and "%(default)" not in text:
            text += " (default: %(default)s)"
        return text


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("plate-env")
    except PackageNotFoundError:
        return "unknown (not installed)"


#: A command-line token that is a negative value, not an option: "-10pi", "-1e-3", "-inf", "-.5".
_NEGATIVE = re.compile(r"^-(\d|\.\d|inf|nan|pi|π)", re.IGNORECASE)


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--omega-n -10pi`` -> ``--omega-n=-10pi``: argparse takes a token starting with "-" for an option unless it
    looks like a plain negative number, and would answer "expected one argument" instead of checking the value."""
    out: list[str] = []
    for token in argv:
        if out and _NEGATIVE.match(token) and out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def _warn_one_line(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                   file: TextIO | None = None, line: str | None = None) -> None:
    print(f"plate-env: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command. Exit codes: 0 done, 1 no estimate, 2 bad input (one line naming it), 3 an internal error
    (one line; ``PLATE_ENV_TRACEBACK=1`` shows the traceback), 130 interrupted (finished probes are printed)."""
    parser = build_parser()
    raw = _join_negative_values(list(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(raw)
    args.argv = raw
    with warnings.catch_warnings():
        warnings.showwarning = _warn_one_line
        try:
            return COMMANDS[args.command].run(args)
        except (CliError, ValueError, OSError) as exc:
            print(f"plate-env {args.command}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"plate-env {args.command}: interrupted", file=sys.stderr)
            return 130
        except Exception as exc:  # noqa: BLE001 - never a traceback for a user; a bug still says what it was
            if os.environ.get("PLATE_ENV_TRACEBACK"):
                raise
            print(f"plate-env {args.command}: internal error: {type(exc).__name__}: {exc} (a bug: please report it; "
                  f"PLATE_ENV_TRACEBACK=1 shows where)", file=sys.stderr)
            return 3


__all__ = ["COMMANDS", "FIT_PROGRESS_ROWS", "MAX_FIT_ROWS", "MAX_SWEEP_PROBES", "TILELINK_MODELS_HELP", "CliError",
           "build_parser", "main", "parse_freqs", "strict_json"]
