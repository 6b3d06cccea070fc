"""Scripted blind policies with the Stable-Baselines3 ``predict`` signature.

All three are *blind*: they read only the observation (the goal of a goal task is part of the
observation; the object's state is not) and most of them ignore even that after planning.

* :class:`PaperSequencePolicy`: the chapter-5 example motion (§5.5.1, motions 1-8), each
  set-point pair held ``duration`` seconds, from the parallel point-contact start.
* :class:`HandlingProcessPolicy`: the chapter-4 handling process (§4.3) for one grasp angle,
  the finger path of :func:`softhand_env.quasistatic.handling_path` fed as set-points.
* :class:`ModelBasedPolicy`: the model-based blind baseline of the goal tasks: at the start
  of an episode it plans open-loop set-points with the quasi-static model
  (:mod:`softhand_env.quasistatic.planner`) for the goal in the observation and then plays them
  without
  any feedback.

Each policy carries :attr:`env_kwargs`, the ``gym.make`` keywords it needs (they all use
``action_mode="absolute", normalize_action=False``: the action is the set-point pair in rad),
and :attr:`episode_steps`, the number of control steps its script lasts (``None``: the env's
own time limit). ``predict(obs, state, episode_start, deterministic)`` accepts a single
observation or a batch of ``n_envs`` and keeps one step counter per environment in ``state``,
so ``stable_baselines3.common.evaluation.evaluate_policy`` works with them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from softhand_env.physics.motions import PAPER_MOTIONS_DEG

#: Keywords every scripted policy needs: the action is the set-point pair in radians.
ABSOLUTE_RAD = {"action_mode": "absolute", "normalize_action": False}


class ScriptedPolicy:
    """Base class: a per-environment step counter and an action schedule.

    Subclasses implement :meth:`start_episode` (optional) and :meth:`action`.
    """

    #: gym.make keywords the policy needs.
    env_kwargs: dict[str, Any] = dict(ABSOLUTE_RAD)
    #: Control steps the script lasts (None: use the environment's time limit).
    episode_steps: int | None = None

    def start_episode(self, index: int, obs: np.ndarray) -> None:
        """Called with the first observation of an episode of environment ``index``."""

    def action(self, index: int, obs: np.ndarray, step: int) -> np.ndarray:
        """Set-points (rad, shape (2,)) at control step ``step`` of the episode."""
        raise NotImplementedError

    def predict(
        self,
        observation: np.ndarray,
        state: np.ndarray | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """SB3-style prediction.

        Parameters
        ----------
        observation : ndarray, shape (obs_dim,) or (n_envs, obs_dim)
        state : ndarray of int, shape (n_envs,), optional
            Step counters returned by the previous call (None: all episodes start now).
        episode_start : ndarray of bool, shape (n_envs,), optional
            True where an episode starts with this observation.
        deterministic : bool
            Ignored (the policies are deterministic).

        Returns
        -------
        actions : ndarray, float64, shape (2,) or (n_envs, 2)
            Set-points in rad.
        state : ndarray of int, shape (n_envs,)
        """
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        batch = obs.reshape(1, -1) if single else obs
        n = batch.shape[0]
        steps = np.zeros(n, dtype=np.int64) if state is None else np.array(state).reshape(n)
        starts = (
            np.ones(n, bool) if state is None or episode_start is None
            else np.asarray(episode_start, bool).reshape(n)
        )
        # float64: a set-point rounded to float32 is off by ~1e-9 rad, which shows in replays
        actions = np.empty((n, 2), dtype=np.float64)
        for i in range(n):
            if starts[i]:
                steps[i] = 0
                self.start_episode(i, batch[i])
            actions[i] = self.action(i, batch[i], int(steps[i]))
        steps = steps + 1
        return (actions[0] if single else actions), steps


class PaperSequencePolicy(ScriptedPolicy):
    """Motions 1-8 of §5.5.1 from the paper's parallel point-contact start (no grasp phase).

    Parameters
    ----------
    duration : float
        Seconds each set-point pair is held (the paper gives none; default 1 s).
    control_dt : float
        Control period of the environment (s), default 0.02.
    """

    def __init__(self, duration: float = 1.0, control_dt: float = 0.02):
        if not (duration > 0 and control_dt > 0):
            raise ValueError("duration and control_dt must be > 0")
        self.steps_per_motion = max(1, round(duration / control_dt))
        self.setpoints = np.radians(np.array(PAPER_MOTIONS_DEG))
        self.env_kwargs = {**ABSOLUTE_RAD, "grasp_duration": 0.0, "control_dt": control_dt}
        self.episode_steps = self.steps_per_motion * len(self.setpoints)

    def action(self, index: int, obs: np.ndarray, step: int) -> np.ndarray:
        k = min(step // self.steps_per_motion, len(self.setpoints) - 1)
        return self.setpoints[k]


class HandlingProcessPolicy(ScriptedPolicy):
    """The handling process of §4.3 (grasp, +20, -40, +40 deg, cycles, back) at one grasp angle.

    Replayed without gravity, as chapter 4 models it (``env_kwargs`` sets ``g = 0``).

    Parameters
    ----------
    grasp_angle_deg : float
        Grasp angle of both fingers (deg); the paper uses 2.4, 3.6, 4.8, 6.0, 7.2.
    step_deg : float
        Set-point increment per control step (deg), default 0.2 (10 deg/s at 20 ms).
    rotation_deg : float
        Rotation of operation 2 (deg); operations 3 and 4 rotate twice as far.
    cycles : int
        Repetitions of operations 3 and 4 (paper: 3).
    settle_steps : int
        Control steps the final set-point is held.
    """

    def __init__(
        self,
        grasp_angle_deg: float,
        step_deg: float = 0.2,
        rotation_deg: float = 20.0,
        cycles: int = 3,
        settle_steps: int = 25,
    ):
        from softhand_env.quasistatic import handling_path

        self.grasp_angle = math.radians(grasp_angle_deg)
        self.setpoints, self.operation = handling_path(
            self.grasp_angle, math.radians(step_deg), math.radians(rotation_deg), cycles
        )
        # the paper's process runs the contact up to 20 % past the fingertip base at 7.2 deg
        # (the quasi-static model flags the same increments): replay it, do not stop there.
        # Chapter 4 ignores gravity, and so does the replay (g = 0): from the point-contact
        # start the object would otherwise hang on friction while the squeeze builds (friction
        # ratio 1.05 > mu in the first control step, a slip); without gravity operations 1-6
        # need at most 0.52
        self.env_kwargs = {
            **ABSOLUTE_RAD,
            "grasp_duration": 0.0,
            "base_tolerance": math.inf,
            "hand_overrides": {"g": 0.0},
        }
        self.episode_steps = len(self.setpoints) - 1 + settle_steps

    def action(self, index: int, obs: np.ndarray, step: int) -> np.ndarray:
        return self.setpoints[min(step + 1, len(self.setpoints) - 1)]

    def end_of_operation(self, op: int) -> int:
        """Control step (0-based) at which the set-point of operation ``op`` has been reached."""
        return int(np.flatnonzero(self.operation == op)[-1]) - 1


class ModelBasedPolicy(ScriptedPolicy):
    """Open-loop blind baseline: quasi-static plan for the observed goal, played without feedback.

    Parameters
    ----------
    targets : sequence of (name, obs_scale)
        The goal entries at the end of the observation: ``("x", scale_m)`` and/or
        ``("theta", scale_rad)``, in observation order (see :meth:`from_env`).
    params : HandParams, optional
        Hand parameters of the planning model (default: Table 5.1, the environment's default).
    grasp_angle_deg : float
        Grasp set-point the environment's reset phase uses (default 6 deg).
    step_deg : float
        Largest set-point change per control step when following the plan (deg).

    Pose goals outside the band that straight finger paths reach fall back to the translation
    plan for x (the baseline is best-effort there, which is why ``SoftHandPose-v0`` needs
    learned rolling manoeuvres).
    """

    def __init__(
        self,
        targets: list[tuple[str, float]],
        params: Any = None,
        grasp_angle_deg: float = 6.0,
        step_deg: float = 0.5,
    ):
        from softhand_env.physics.params import HandParams

        names = tuple(name for name, _ in targets)
        if names not in (("x",), ("theta",), ("x", "theta")):
            raise ValueError(f"targets must be x, theta or (x, theta) (got {names})")
        self.targets = list(targets)
        self.params = params if params is not None else HandParams()
        self.grasp_angle = math.radians(grasp_angle_deg)
        self.step = math.radians(step_deg)
        self.env_kwargs = dict(ABSOLUTE_RAD)
        self._plans: dict[int, np.ndarray] = {}

    @classmethod
    def from_env(cls, env: Any, **kwargs: Any) -> ModelBasedPolicy:
        """Build the baseline for a goal environment (reads its task targets and hand)."""
        base = env.unwrapped
        targets = [(t.name, t.obs_scale) for t in base.task.targets]
        grasp = float(np.degrees(base.config.grasp_setpoint[0]))
        return cls(targets, params=base.config.params, grasp_angle_deg=grasp, **kwargs)

    def goal(self, obs: np.ndarray) -> dict[str, float]:
        """Goal (SI) decoded from the last entries of an observation."""
        tail = obs[len(obs) - len(self.targets) :]
        return {name: float(v) * scale for (name, scale), v in zip(self.targets, tail, strict=True)}

    def plan(self, goal: dict[str, float]) -> np.ndarray:
        """Set-points (K, 2) in rad from the grasp to the goal, sub-sampled to ``step_deg``."""
        from softhand_env.quasistatic import planner

        kw: dict[str, Any] = {"params": self.params, "grasp_angle": self.grasp_angle}
        try:
            if "x" in goal and "theta" in goal:
                try:
                    plan = planner.plan_pose(goal["x"], goal["theta"], **kw)
                except ValueError:
                    plan = planner.plan_translation(goal["x"], **kw)
            elif "x" in goal:
                plan = planner.plan_translation(goal["x"], **kw)
            else:
                plan = planner.plan_reorientation(goal["theta"], **kw)
            sp = plan.setpoints
        except ValueError:
            # unreachable even by rotation: stay at the grasp
            sp = np.full((1, 2), self.grasp_angle)
        stride = max(1, round(self.step / planner.DEFAULT_STEP))
        idx = np.unique(np.append(np.arange(0, len(sp), stride), len(sp) - 1))
        return sp[idx]

    def start_episode(self, index: int, obs: np.ndarray) -> None:
        self._plans[index] = self.plan(self.goal(obs))

    def action(self, index: int, obs: np.ndarray, step: int) -> np.ndarray:
        sp = self._plans[index]
        return sp[min(step + 1, len(sp) - 1)]


__all__ = [
    "ABSOLUTE_RAD",
    "HandlingProcessPolicy",
    "ModelBasedPolicy",
    "PaperSequencePolicy",
    "ScriptedPolicy",
]
