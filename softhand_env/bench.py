"""Shortcut: ``python -m softhand_env.bench`` runs :mod:`softhand_env.tools.bench`."""

from softhand_env.tools.bench import main

if __name__ == "__main__":
    raise SystemExit(main())
