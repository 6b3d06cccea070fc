"""Scripted blind policies with the Stable-Baselines3 ``predict`` signature.

:mod:`.policies` (the paper's motion sequence, the chapter-4 handling process, the
model-based baseline and their base class) and :mod:`.loop_plan` (the rolling-loop plan of
``SoftHandPose-v0``); their names are importable from ``agents.scripted`` itself.
"""

from agents.scripted.loop_plan import LoopPlanPolicy
from agents.scripted.policies import (
    ABSOLUTE_RAD,
    HandlingProcessPolicy,
    ModelBasedPolicy,
    PaperSequencePolicy,
    ScriptedPolicy,
)

__all__ = ["ABSOLUTE_RAD", "HandlingProcessPolicy", "LoopPlanPolicy", "ModelBasedPolicy",
           "PaperSequencePolicy", "ScriptedPolicy"]
