"""The open-loop rolling plan for ``SoftHandPose-v0`` (the plan the residual agent corrects).

Reaching x and theta independently needs *rolling loops* in finger-angle space: open the
grasp by ``a``, rotate both fingers by ``b``, close the grasp, rotate back. The closed path
rolls the object by about ``-gain * b`` (area-proportional; measured on the chapter-5 model
from the 6 deg grasp with ``a = 4`` deg at 1 deg per step: b = 2.5, 5, 7.5, 10, 12.5 deg ->
-0.55, -1.27, -2.13, -2.94, -3.78 deg) while x stays within about 0.1 mm. A pure per-step
policy trained from scratch did not discover such loops in our budget (PPO stayed at the
rotation-coupled straight-line solution, 15 % success, like the model-based baseline), so
the Pose agent learns a *residual* on top of a plan that contains them:

* :class:`LoopPlanPolicy`: open-loop, blind plan for a goal read from the observation: ``n``
  equal loops at the grasp (their total roll is the residual ``theta* - coupling * x*`` that
  the final translation does not provide), then the straight rotation of both fingers to x*.
  A linear model with three measured constants; it is a scripted policy in its own right
  (``predict`` API of :mod:`agents.scripted`).

:class:`~agents.wrappers.residual.ResidualWrapper` lets an agent learn a residual on it.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from agents.scripted.policies import ABSOLUTE_RAD, ScriptedPolicy


class LoopPlanPolicy(ScriptedPolicy):
    """Loops at the grasp for the residual roll, then the translation to x* (open loop).

    Parameters
    ----------
    targets : list of (name, obs_scale)
        Goal entries at the end of the observation, as for
        :class:`~agents.scripted.ModelBasedPolicy` (``from_env`` reads them).
    grasp_deg : float
        Grasp set-point of both fingers (deg), the env's ``grasp_setpoint_deg``.
    squeeze_deg : float
        How far a loop opens the grasp (``a``, deg).
    max_loop_deg : float
        Largest rotation ``b`` of one loop (deg); the residual is split into equal loops.
    gain : float
        Roll per degree of ``b`` (deg/deg), measured 0.29 (module doc).
    coupling : float
        theta change per mm of x along the straight translation (deg/mm), measured 0.77.
    mm_per_deg : float
        x change per degree of finger rotation along the translation (mm/deg), measured 1.34.
    step_deg : float
        Largest set-point change per control step (deg).
    """

    def __init__(
        self,
        targets: list[tuple[str, float]],
        grasp_deg: float = 6.0,
        squeeze_deg: float = 4.0,
        max_loop_deg: float = 12.0,
        gain: float = 0.29,
        coupling: float = 0.77,
        mm_per_deg: float = 1.34,
        step_deg: float = 1.0,
    ):
        if tuple(name for name, _ in targets) != ("x", "theta"):
            raise ValueError("LoopPlanPolicy needs a pose goal (x, theta)")
        self.targets = list(targets)
        self.grasp = grasp_deg
        self.squeeze = squeeze_deg
        self.max_loop = max_loop_deg
        self.gain = gain
        self.coupling = coupling
        self.mm_per_deg = mm_per_deg
        self.step = step_deg
        self.env_kwargs = dict(ABSOLUTE_RAD)
        self._plans: dict[int, np.ndarray] = {}

    @classmethod
    def from_env(cls, env: gym.Env, **kwargs: Any) -> LoopPlanPolicy:
        """Build the plan for a pose env (reads its goal scales and grasp set-point)."""
        base: Any = env.unwrapped  # a SoftHandEnv
        targets = [(t.name, t.obs_scale) for t in base.task.targets]
        grasp = float(np.degrees(base.config.grasp_setpoint[0]))
        return cls(targets, grasp_deg=grasp, **kwargs)

    def goal(self, obs: np.ndarray) -> tuple[float, float]:
        """(x* in mm, theta* in deg) decoded from the last two observation entries."""
        (_, sx), (_, st) = self.targets
        return float(obs[-2]) * sx * 1e3, math.degrees(float(obs[-1]) * st)

    def corners(self, x_mm: float, theta_deg: float) -> list[np.ndarray]:
        """Corner set-points (deg) of the plan: loops, then the translation."""
        g, a = self.grasp, self.squeeze

        def sp(phi: float, s: float) -> np.ndarray:
            return np.array([s + phi, s - phi])

        residual = theta_deg - self.coupling * x_mm
        n = math.ceil(abs(residual) / (self.gain * self.max_loop) - 1e-9)
        pts = [sp(0.0, g)]
        if n > 0:
            b = -residual / (self.gain * n)  # a loop with +b rolls the object by -gain * b
            pts += [sp(0.0, g - a), sp(b, g - a), sp(b, g), sp(0.0, g)] * n
        pts.append(sp(-x_mm / self.mm_per_deg, g))
        return pts

    def plan(self, x_mm: float, theta_deg: float) -> np.ndarray:
        """Set-points (K, 2) in rad along the corners, at most ``step_deg`` apart."""
        pts = self.corners(x_mm, theta_deg)
        out = [pts[0]]
        for a, b in zip(pts[:-1], pts[1:], strict=True):
            n = max(1, math.ceil(float(np.max(np.abs(b - a))) / self.step - 1e-9))
            out += [a + (b - a) * k / n for k in range(1, n + 1)]
        return np.radians(np.array(out))

    def start_episode(self, index: int, obs: np.ndarray) -> None:
        self._plans[index] = self.plan(*self.goal(obs))

    def action(self, index: int, obs: np.ndarray, step: int) -> np.ndarray:
        sp = self._plans[index]
        return sp[min(step + 1, len(sp) - 1)]
