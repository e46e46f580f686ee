"""The README's path before the layers (``from plate_env.benchmark import evaluate``): it moved to
:mod:`plate_env.bench`. Importing this module fails with a message naming the new path (no import hook)."""

raise ImportError("plate_env.benchmark moved to plate_env.bench: use `from plate_env.bench import evaluate` (and the "
                  "rest of plate_env.benchmark's names from plate_env.bench)")
