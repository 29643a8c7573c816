"""The ``millctl`` command line: one module per command group, registered here.

Each command module exposes ``register(subparsers)``, which adds its parser
and sets ``handler`` to a function ``(args) -> int``. Modules import heavy
dependencies (numpy, numba, scipy, pydantic, httpx, python-can, rich) inside
their handlers, never at module level, so that ``millctl --help`` and the
client commands start fast; the files a command names are checked
(:mod:`millctl.cli.precheck`) before its handler runs, so a bad file is refused
before anything heavy loads (tests/unit/test_cli_startup.py holds both).
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import os
import sys
from collections.abc import Sequence

from millctl import __version__
from millctl.errors import ExitCode, MillctlError

COMMAND_MODULES = (
    "millctl.cli.config_cmd",
    "millctl.cli.limits_cmd",
    "millctl.cli.physics_cmd",
    "millctl.cli.recipe_cmd",
    "millctl.cli.study_cmd",
    "millctl.cli.bus_cmd",
    "millctl.cli.service_cmd",
    "millctl.cli.client_cmd",
    "millctl.cli.tui_cmd",
    "millctl.cli.report_cmd",
    "millctl.cli.bench_cmd",
    "millctl.cli.completion_cmd",
)
"""Command modules, in the order ``--help`` lists them."""

EPILOG = """\
exit codes:
  0  ok
  1  invalid input (config, recipe, argument, request)
  2  interlock refusal or trip, or an aborted run
  3  bus, node or service error
  4  internal error (rerun with --debug for the traceback)
  130  interrupted (Ctrl+C)
  141  stdout closed by its reader (e.g. `| head`): ended quietly

--json: one document on stdout, {"schema": 1, "command", "ok", "result" | "error"}; errors too

configuration: --config FILE > $MILLCTL_CONFIG > ./config/mill.toml > packaged default
"""


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors exit with ExitCode.INVALID_INPUT (as a JSON document with --json)."""

    json_requested = False
    """Set by :func:`main` when ``--json`` is among the arguments: an argument error is a JSON document too."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.print_usage(sys.stderr)
        if _Parser.json_requested:
            from millctl.cli.failures import EXIT_NAMES
            from millctl.cli.output import json_document

            command = self.prog.removeprefix("millctl").strip()
            error = {"code": EXIT_NAMES[ExitCode.INVALID_INPUT], "message": f"{self.prog}: {message}",
                     "exit_code": int(ExitCode.INVALID_INPUT), "usage": self.format_usage().strip()}
            try:
                sys.stdout.write(json.dumps(json_document(command, error=error), indent=2, ensure_ascii=False))
                sys.stdout.write("\n")
                sys.stdout.flush()
            except BrokenPipeError:
                self.exit(_stdout_gone())
        self.exit(int(ExitCode.INVALID_INPUT), f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, with every registered command."""
    parser = _Parser(
        prog="millctl",
        description="Control and test bench for a horizontal vibratory rod mill.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"millctl {__version__}")
    parser.add_argument("--config", metavar="FILE", help="mill configuration (TOML)")
    parser.add_argument("--debug", action="store_true", help="debug logging and tracebacks on errors")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    for command in _leaves(parser):
        if not any("--json" in action.option_strings for action in command._actions):
            command.add_argument("--json", action="store_true", help=JSON_HELP)
    return parser


JSON_HELP = "one JSON document on stdout, whatever the outcome (see millctl --help)"


def _leaves(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """Every parser of a command that runs (one without subcommands)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [parser]
    return [leaf for action in subs for sub in dict.fromkeys(action.choices.values()) for leaf in _leaves(sub)]


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``millctl``; return its exit code."""
    from millctl.cli.output import json_mode
    from millctl.cli.precheck import precheck

    parser = build_parser()
    words = list(sys.argv[1:] if argv is None else argv)
    _Parser.json_requested = "--json" in words[: words.index("--") if "--" in words else len(words)]
    args = parser.parse_args(words)
    _configure_logging(args.debug)
    if not getattr(args, "handler", None):
        parser.print_help(sys.stderr)
        return int(ExitCode.INVALID_INPUT)
    try:
        with json_mode(bool(getattr(args, "json", False))):
            precheck(args)  # the named files, before the handler imports numpy, numba, pydantic, ...
            code = int(args.handler(args))
        code = _outcome(args, code)
        sys.stdout.flush()  # here, where a reader that left is a BrokenPipeError (141), not at exit (120)
        return code
    except BrokenPipeError:
        return _stdout_gone()
    except (MillctlError, KeyboardInterrupt) as exc:
        if args.debug and isinstance(exc, MillctlError):
            logging.exception("millctl failed")
        return _fail(args, exc)
    except Exception as exc:
        if args.debug:
            raise
        return _fail(args, exc)


def _configure_logging(debug: bool) -> None:
    """Warnings as plain lines on stderr; with --debug everything, timestamped, python-can's own lines too.

    python-can logs a warning when it imports a driver whose vendor library is missing ("Kvaser canlib is
    unavailable."); a bus that then cannot open is reported once, saying what to install
    (millctl.protocol.drivers), so without --debug python-can speaks only of errors.
    """
    if debug:
        logging.basicConfig(level=logging.DEBUG, stream=sys.stderr,
                            format="%(asctime)s %(levelname)s %(name)s: %(message)s")
        return
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="millctl: %(levelname)s: %(message)s")
    logging.getLogger("can").setLevel(logging.ERROR)


def _outcome(args: argparse.Namespace, code: int) -> int:
    """With --json, a command that printed no document of its own gets one: its exit code, in the envelope."""
    from millctl.cli.failures import EXIT_NAMES
    from millctl.cli.output import documents_printed, print_json, print_json_error

    if getattr(args, "json", False) and documents_printed() == 0:
        if code == ExitCode.OK:
            print_json(args, {"exit_code": code})
        else:
            name = EXIT_NAMES.get(ExitCode(code), "error") if code in {int(c) for c in ExitCode} else "error"
            print_json_error(args, {"code": name, "exit_code": code,
                                    "message": f"exit {code} ({name}): the reason is on stderr"})
    return code


def _fail(args: argparse.Namespace, exc: BaseException) -> int:
    """Say what failed (stderr; and as the JSON error on stdout with --json); return the exit code."""
    from millctl.cli.failures import describe_failure
    from millctl.cli.output import print_json_error

    code, message, error = describe_failure(exc)
    if getattr(args, "json", False):
        try:
            print_json_error(args, error)
        except BrokenPipeError:
            return _stdout_gone()
    print(f"millctl: {message}", file=sys.stderr)
    return code


def _stdout_gone() -> int:
    """The reader of stdout left (``| head``): end quietly, with no traceback at exit either."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return int(ExitCode.BROKEN_PIPE)


__all__ = ["COMMAND_MODULES", "build_parser", "main"]
