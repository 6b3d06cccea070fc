"""Published name of :mod:`agents.wrappers.time_feature`: run configs name the wrapper as
``agents.time_feature.TimeFeature`` (``env_wrapper`` entries, read by this package's loader and
by ``rl_zoo3``), so the path keeps importing the same classes."""

from agents.wrappers.time_feature import TimeFeature, VecTimeFeature

__all__ = ["TimeFeature", "VecTimeFeature"]
