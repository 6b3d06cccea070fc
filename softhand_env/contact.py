"""Shortcut: ``softhand_env.contact`` is :mod:`softhand_env.physics.contact` (the fingertip
contact models of chapters 2-3), kept under its published name."""

from softhand_env.physics.contact import *  # noqa: F403
from softhand_env.physics.contact import __all__  # noqa: F401
