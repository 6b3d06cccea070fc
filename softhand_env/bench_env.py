"""Shortcut: ``python -m softhand_env.bench_env`` runs :mod:`softhand_env.tools.bench_env`."""

from softhand_env.tools.bench_env import main

if __name__ == "__main__":
    main()
