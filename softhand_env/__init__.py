"""softhand-env: blind manipulation with a soft-fingered, two-joint robotic hand.

Importing the package registers the Gymnasium environments (see :mod:`softhand_env.envs`).
"""

__version__ = "0.1.0"

from softhand_env.envs import register_envs as _register_envs  # noqa: E402

_register_envs()
