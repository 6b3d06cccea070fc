"""Deprecated alias: ``python -m softhand_env.bench`` runs :mod:`softhand_env.tools.bench`
(emits a DeprecationWarning); run ``python -m softhand_env.tools.bench`` instead."""

import warnings

from softhand_env.tools.bench import main

warnings.warn("softhand_env.bench is deprecated: use softhand_env.tools.bench",
              DeprecationWarning, stacklevel=2)

if __name__ == "__main__":
    raise SystemExit(main())
