"""The physics stack of the soft hand, bottom to top.

:mod:`.params` (hand parameters, SI) -> :mod:`.contact` (chapter 2-3 fingertip models) ->
:mod:`.model` (chapter-5 dynamic model as compiled functions) -> :mod:`.integrate` (RK
tableaus) / :mod:`.kernel` (compiled RK4 kernels, one system or N in lanes) /
:mod:`.rosenbrock` (compiled ROS2 kernels at millisecond steps, ``integrator="ros2"``) ->
:mod:`.failure` (failure classification) -> :mod:`.hand` (:class:`HandPhysics`: N hands,
stepping, rollback, named read-outs); beside them :mod:`.friction` (friction ratio, tension and
slip from the contact impulses), :mod:`.stability` (a-priori stability check of RK4 and ROS2) and
:mod:`.validity` (validated range of the contact model); :mod:`.motions` runs set-point
sequences through :mod:`.hand` (the paper's motions 1-8); :mod:`.reference` is an independent
plain-NumPy model for cross-checks.

The names of :mod:`.hand` are available here (``from softhand_env.physics import
HandPhysics``); they are imported on first use, so that importing a light submodule such as
:mod:`.params` does not load the compiled kernels.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from softhand_env.physics.hand import (
        FLAG_NAMES,
        RK4_REAL_STABILITY,
        HandPhysics,
        HandReadouts,
        PhysicsError,
        StepStatus,
        check_rk4_stability,
        describe_flags,
        rk4_stability_margins,
        warn_if_unstable,
    )


def __getattr__(name: str) -> Any:
    if name in __all__:
        from softhand_env.physics import hand

        return getattr(hand, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "FLAG_NAMES",
    "RK4_REAL_STABILITY",
    "HandPhysics",
    "HandReadouts",
    "PhysicsError",
    "StepStatus",
    "check_rk4_stability",
    "describe_flags",
    "rk4_stability_margins",
    "warn_if_unstable",
]
