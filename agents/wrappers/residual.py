"""Residual learning on top of an open-loop rolling plan, for ``SoftHandPose-v0``.

The plan is :class:`~agents.scripted.loop_plan.LoopPlanPolicy` (rolling loops at the grasp, then
the translation; its module doc gives the measurements behind it).

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

from agents.scripted.loop_plan import LoopPlanPolicy
from softhand_env.envs.observation import ANGLE_SCALE


class ResidualWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
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
        gym.utils.RecordConstructorArgs.__init__(self, delta_deg=delta_deg,
                                                 max_offset_deg=max_offset_deg, **plan_kwargs)
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
