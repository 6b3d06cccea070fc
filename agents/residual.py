"""Residual learning on top of an open-loop rolling plan, for ``SoftHandPose-v0``.

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
* :class:`ResidualWrapper`: the agent's action (delta mode, ``delta_deg`` per step) moves an
  *offset* that is added to the plan's set-points, ``u_t = plan(t) + offset_t`` with
  ``|offset| <= max_offset_deg``; the observation is the env's (joint sensing + goal) plus the
  offset, the plan's current set-points and the remaining time, all of it blind.

The wrapper needs the env in ``action_mode="absolute", normalize_action=False`` (the plan is
in radians); ``SoftHandPose-v0``'s entry in ``configs/agents/ppo.yml`` sets both.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.scripted import ABSOLUTE_RAD, ScriptedPolicy
from softhand_env.envs.observation import ANGLE_SCALE


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


class ResidualWrapper(gym.Wrapper):
    """The agent steers an offset added to the set-points of :class:`LoopPlanPolicy`.

    Action: ``Box(-1, 1, (2,))``, the change of the offset in units of ``delta_deg``; the
    offset is clipped to ``+-max_offset_deg`` per finger; set-points ``u_t = plan(t) + offset``
    (then clipped to the joint range by the env). Observation: the env's observation followed
    by the offset / ``max_offset_deg`` (2), the plan's set-points / 30 deg (2) and the
    remaining time fraction (1).

    Parameters
    ----------
    env : gym.Env
        A pose env made with ``action_mode="absolute", normalize_action=False``.
    delta_deg : float
        Largest offset change per control step (deg).
    max_offset_deg : float
        Largest offset per finger (deg).
    **plan_kwargs
        Keywords of :class:`LoopPlanPolicy` (calibration constants, loop size).
    """

    def __init__(
        self, env: gym.Env, delta_deg: float = 0.5, max_offset_deg: float = 5.0, **plan_kwargs: Any
    ):
        super().__init__(env)
        actions = env.unwrapped.config.actions  # type: ignore[attr-defined]
        if actions.mode != "absolute" or actions.normalize:
            raise ValueError(
                'ResidualWrapper needs env kwargs action_mode="absolute", normalize_action=False'
            )
        if not (delta_deg > 0 and max_offset_deg > 0):
            raise ValueError("delta_deg and max_offset_deg must be > 0")
        self.plan = LoopPlanPolicy.from_env(env, **plan_kwargs)
        self.delta = math.radians(delta_deg)
        self.max_offset = math.radians(max_offset_deg)
        spec = env.spec
        self.max_steps = int(spec.max_episode_steps) if spec and spec.max_episode_steps else 1000
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        inner: Any = env.observation_space  # a Box
        self.observation_space = spaces.Box(
            np.concatenate([inner.low, -np.ones(2), -np.full(2, 100.0), [0.0]]).astype(np.float32),
            np.concatenate([inner.high, np.ones(2), np.full(2, 100.0), [1.0]]).astype(np.float32),
            dtype=np.float32,
        )
        self._offset = np.zeros(2)
        self._t = 0
        self._base_obs: Any = None  # ndarray after reset

    def _planned(self) -> np.ndarray:
        return self.plan.action(0, self._base_obs, self._t)

    def _observe(self, obs: np.ndarray) -> np.ndarray:
        extra = np.concatenate([
            self._offset / self.max_offset,
            self._planned() / ANGLE_SCALE,
            [max(0.0, 1.0 - self._t / self.max_steps)],
        ])
        return np.concatenate([obs, extra]).astype(np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._base_obs = obs
        self.plan.start_episode(0, obs)
        self._offset = np.zeros(2)
        self._t = 0
        return self._observe(obs), info

    def step(self, action: np.ndarray):
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        self._offset = np.clip(self._offset + a * self.delta, -self.max_offset, self.max_offset)
        setpoint = self._planned() + self._offset
        obs, reward, terminated, truncated, info = self.env.step(setpoint)
        self._t += 1
        return self._observe(obs), reward, terminated, truncated, info
