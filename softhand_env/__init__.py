"""softhand-env: blind manipulation with a soft-fingered, two-joint robotic hand.

Importing the package registers the Gymnasium environments (see :mod:`softhand_env.envs`).
"""

__version__ = "0.1.0"
