"""``millctl completion SHELL``: print a shell completion script (shtab) for every command and flag."""

from __future__ import annotations

import argparse

from millctl.errors import ExitCode

SHELLS = ("bash", "zsh", "tcsh")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``completion``."""
    parser = subparsers.add_parser(
        "completion",
        help="print a shell completion script",
        description="Print a completion script for SHELL. Install, e.g. for bash: "
        "millctl completion bash > ~/.local/share/bash-completion/completions/millctl",
    )
    parser.add_argument("shell", choices=SHELLS, help="the shell to complete in")
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    import shtab

    from millctl.cli import build_parser

    script = shtab.complete(build_parser(), shell=args.shell)
    if args.json:
        from millctl.cli.output import print_json

        print_json(args, {"shell": args.shell, "script": script})
        return int(ExitCode.OK)
    print(script, end="")
    return int(ExitCode.OK)


__all__ = ["SHELLS", "register"]
