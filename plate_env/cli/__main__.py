"""``python -m plate_env.cli``: the ``plate-env`` command."""

from plate_env.cli import main

raise SystemExit(main())
