"""Published name of :mod:`agents.wrappers.residual` (and of the loop plan,
:mod:`agents.scripted.loop_plan`): run configs name the wrapper as
``agents.residual.ResidualWrapper`` (``env_wrapper`` entries, read by this package's loader and
by ``rl_zoo3``), so the path keeps importing the same classes."""

from agents.scripted.loop_plan import LoopPlanPolicy
from agents.wrappers.residual import ResidualWrapper

__all__ = ["LoopPlanPolicy", "ResidualWrapper"]
