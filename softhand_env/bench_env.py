"""Deprecated alias: ``python -m softhand_env.bench_env`` runs :mod:`softhand_env.tools.bench_env`
(emits a DeprecationWarning); run ``python -m softhand_env.tools.bench_env`` instead."""

import warnings

from softhand_env.tools.bench_env import main

warnings.warn("softhand_env.bench_env is deprecated: use softhand_env.tools.bench_env",
              DeprecationWarning, stacklevel=2)

if __name__ == "__main__":
    main()
