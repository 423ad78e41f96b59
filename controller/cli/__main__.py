"""``python -m controller.cli``: the seamguide command line."""

from controller.cli.main import main

raise SystemExit(main())
