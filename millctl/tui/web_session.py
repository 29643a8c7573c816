"""One browser connection's TUI (``millctl tui --web`` runs this per page): read-only until it takes control.

Run by textual-serve with its web driver (``TEXTUAL_DRIVER``); not a command for people.
"""

from __future__ import annotations

import argparse

from millctl.tui.app import MillApp


def main(argv: list[str] | None = None) -> int:
    """Run the TUI on ``--socket`` as a web session (commands need the lease taken with ``c``)."""
    parser = argparse.ArgumentParser(prog="python -m millctl.tui.web_session",
                                     description="one page of `millctl tui --web` (started by it)")
    parser.add_argument("--socket", required=True, metavar="PATH", help="the service socket")
    parser.add_argument("--config", metavar="FILE", help="the configuration the service socket came from")
    parser.add_argument("--simulated", action="store_true", help="the service is `millctl tui --sim`'s")
    args = parser.parse_args(argv)
    MillApp(args.socket, config=args.config, sim=args.simulated, web=True).run()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
