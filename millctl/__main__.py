"""``python -m millctl`` runs the command-line interface."""

from millctl.cli import main

raise SystemExit(main())
