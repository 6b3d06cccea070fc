"""Deprecated alias: ``softhand_env.tools.simulate`` is :mod:`softhand_env.physics.motions`
(set-point sequences of the dynamic model, the paper's motions 1-8); importing it emits a
DeprecationWarning. Import :mod:`softhand_env.physics.motions` instead."""

import warnings

from softhand_env.physics.motions import (  # noqa: F401
    PAPER_MOTIONS_DEG,
    Trajectory,
    run_paper_motions,
    run_setpoint_sequence,
)

warnings.warn("softhand_env.tools.simulate is deprecated: import softhand_env.physics.motions",
              DeprecationWarning, stacklevel=2)
