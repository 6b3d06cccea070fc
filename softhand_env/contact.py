"""Deprecated alias: ``softhand_env.contact`` is :mod:`softhand_env.physics.contact` (the
fingertip contact models of chapters 2-3), kept under its published name; importing it emits a
DeprecationWarning. Import :mod:`softhand_env.physics.contact` instead."""

import warnings

from softhand_env.physics.contact import *  # noqa: F403
from softhand_env.physics.contact import __all__  # noqa: F401

warnings.warn("softhand_env.contact is deprecated: import softhand_env.physics.contact",
              DeprecationWarning, stacklevel=2)
