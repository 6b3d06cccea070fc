"""Published name of :mod:`agents.wrappers.action_history`: run configs name the wrapper as
``agents.action_history.ActionHistory`` (``env_wrapper`` entries, read by this package's loader
and by ``rl_zoo3``), so the path keeps importing the same classes."""

from agents.wrappers.action_history import ActionHistory, VecActionHistory

__all__ = ["ActionHistory", "VecActionHistory"]
