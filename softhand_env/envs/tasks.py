"""Tasks: goal sampling, reward terms, success and termination (dm_control's Task role).

A task never touches the integrator; the environment hands it the object's pose (a physics
read-out) and the step's failure classification after every control step
(:meth:`Task.score`, into the episode batch's arrays, :mod:`softhand_env.envs.transition`).
A goal task scores in one compiled function (:func:`score_rows`), for one environment, a
batch, and the relabelled goals of :meth:`Task.evaluate` alike.

Tasks (variants are constructor arguments, not new classes):

* :class:`NoTask` (``"none"``): no goal, no reward terms; for scripted replay and evaluation.
* :class:`GoalTask` with ``targets=("theta",)`` (``"reorient"``), ``("x",)`` (``"translate"``)
  or ``("x", "theta")`` (``"pose"``).

Reward of a goal task (every term is copied to ``info``; reward = sum of the terms)::

    reward_goal    =  goal_weight * exp(-e),   e = sum_k |p_k - g_k| / scale_k
    reward_success =  success_weight * is_success
    reward_ctrl    = -ctrl_weight * |u_t - u_{t-1}|^2 / max_delta^2
    reward_failure = -failure_weight * failed

``p_k`` is the object's x (m) or theta (rad), ``g_k`` its target, ``u`` the set-point pair (rad),
``max_delta`` the action's set-point bound per step (rad), ``failed`` a physical termination
(:mod:`softhand_env.physics.failure`).
``is_success`` = every ``|p_k - g_k| <= tolerance_k`` while the object is grasped.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from softhand_env.envs.observation import ANGLE_SCALE, POSITION_SCALE
from softhand_env.envs.options import check_keyword
from softhand_env.envs.task_configs import TASK_TARGETS, load_task_config
from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.params import is_finite_real

#: The goal task's keywords that change the reward only (not the goals, success, termination
#: or anything observed): a policy trained under other values plays the same task.
REWARD_KWARGS = (
    "x_scale_mm",
    "theta_scale_deg",
    "goal_weight",
    "success_weight",
    "ctrl_weight",
    "failure_weight",
)

#: Constructor keywords that configure a goal task (``None`` in the env signature = task config).
TASK_KWARGS = (
    "goal_x_range_mm",
    "goal_theta_range_deg",
    "x_tolerance_mm",
    "theta_tolerance_deg",
    *REWARD_KWARGS,
    "terminate_on_success",
)

#: Indices of x (m) and theta (rad) in an object pose (x, y, theta).
POSE_X = 0
POSE_THETA = 2

#: Reward term names of goal tasks, in summation order.
GOAL_TERMS = ("reward_goal", "reward_success", "reward_ctrl", "reward_failure")


@njit(cache=True)
def score_rows(pose, goal, ctrl, failed, grasped, rows, index, tolerance, scale, weights,
               terms, success, reward):
    """The goal-task reward of the environments ``rows`` (int (K,)), in place (module doc).

    Parameters
    ----------
    pose : ndarray, shape (N, P)
        Object coordinates; column ``index[k]`` is target k's (m or rad).
    goal : ndarray, shape (N, goal_dim)
        Goals (SI).
    ctrl : ndarray, shape (N,)
        |u_t - u_{t-1}|^2 / max_delta^2.
    failed, grasped : ndarray of bool, shape (N,)
    rows : ndarray of int, shape (K,)
    index : ndarray of int, shape (goal_dim,)
    tolerance, scale : ndarray, shape (goal_dim,)
        Success tolerance and error scale per target (SI).
    weights : ndarray, shape (4,)
        goal, success, ctrl and failure weights.
    terms : ndarray, shape (4, N)
        Receives the four terms (:data:`GOAL_TERMS` order) in the columns ``rows``.
    success : ndarray of bool, shape (N,)
    reward : ndarray, shape (N,)
        Receives the terms' sum, added in their order.
    """
    for k in range(rows.shape[0]):
        s = rows[k]
        ok = grasped[s] and not failed[s]  # a failed step never succeeds
        err = 0.0
        for t in range(index.shape[0]):
            d = abs(pose[s, index[t]] - goal[s, t])
            err = err + d / scale[t]
            ok = ok and d <= tolerance[t]
        t0 = weights[0] * np.exp(-err)
        t1 = weights[1] * (1.0 if ok else 0.0)
        t2 = 0.0 - weights[2] * ctrl[s]
        t3 = 0.0 - weights[3] * (1.0 if failed[s] else 0.0)
        terms[0, s] = t0
        terms[1, s] = t1
        terms[2, s] = t2
        terms[3, s] = t3
        success[s] = ok
        reward[s] = ((t0 + t1) + t2) + t3


@dataclass(frozen=True)
class Target:
    """One controlled object coordinate of a goal task (SI units).

    Attributes
    ----------
    name : str
        ``"x"`` (object x, m) or ``"theta"`` (object angle, rad).
    index : int
        Index of the coordinate in the object pose (x, y, theta): :data:`POSE_X` or
        :data:`POSE_THETA`.
    goal_range : float
        Targets are sampled uniformly from [-goal_range, goal_range].
    tolerance : float
        Success when |p - g| <= tolerance.
    scale : float
        Error scale of ``reward_goal``.
    obs_scale : float
        The target appears in the observation divided by this.
    """

    name: str
    index: int
    goal_range: float
    tolerance: float
    scale: float
    obs_scale: float


class Task:
    """Base task: no goal, no reward (``"none"``, used by ``SoftHand-v0``)."""

    name = "none"
    terms: tuple[str, ...] = ()
    targets: tuple[Target, ...] = ()
    terminate_on_success = False

    @property
    def goal_dim(self) -> int:
        """Number of goal coordinates."""
        return len(self.targets)

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        """Draw a goal (SI units), shape (goal_dim,), from ``rng`` (the env's ``np_random``)."""
        return self.sample_goals((rng,))[0]

    def sample_goals(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """:meth:`sample_goal` of K episodes, row k from ``rngs[k]``: shape (K, goal_dim)."""
        return np.zeros((len(rngs), 0))

    def goal_pose(self, pose: np.ndarray, goal: np.ndarray) -> tuple[float, float] | None:
        """Object (x, theta) at the goal for drawing: targets from ``goal``, the rest from the
        object pose ``pose`` (x, y, theta); None without a goal."""
        if not self.targets:
            return None
        at_goal = {"x": float(pose[POSE_X]), "theta": float(pose[POSE_THETA])}
        for target, g in zip(self.targets, goal, strict=True):
            at_goal[target.name] = float(g)
        return at_goal["x"], at_goal["theta"]

    def evaluate(
        self, pose: Any, goal: tuple[Any, ...], ctrl: Any, failed: Any, grasped: Any,
        scalar: bool | None = None,
    ) -> tuple[tuple[Any, ...], Any]:
        """Reward terms (ordered as :attr:`terms`) and success for object pose(s) ``pose``.

        Parameters
        ----------
        pose : sequence or mapping
            Object (x, y, theta) (m, m, rad) after the step, coordinate first: ``pose[k]``
            (k = 0, 1, 2, or the targets' indices of a mapping) a scalar or an array.
        goal : tuple of float or of ndarray
            Goal coordinates (SI), one entry per target.
        ctrl : float or ndarray
            |u_t - u_{t-1}|^2 / max_delta^2 (dimensionless).
        failed, grasped : bool or ndarray of bool
            The step's failure classification (:class:`~softhand_env.physics.StepStatus`),
            slip and tension included when they terminate. Success requires ``grasped`` and
            not ``failed``: a step that over-compresses or slips never counts as success, even
            with the object on the goal.
        scalar : bool, optional
            Return Python floats and a bool; None (default): when every argument is a scalar.
            Otherwise the terms are float arrays and success a bool array of the arguments'
            broadcast shape.
        """
        return (), False


NoTask = Task


class GoalTask(Task):
    """Bring the object's x and/or theta to a target sampled at reset (see module doc)."""

    terms = GOAL_TERMS

    def __init__(
        self,
        name: str,
        targets: tuple[Target, ...],
        goal_weight: float,
        success_weight: float,
        ctrl_weight: float,
        failure_weight: float,
        terminate_on_success: bool,
    ):
        if not targets:
            raise ValueError("a goal task needs at least one target")
        for key, value in (
            ("goal_weight", goal_weight),
            ("success_weight", success_weight),
            ("ctrl_weight", ctrl_weight),
            ("failure_weight", failure_weight),
        ):
            check_keyword(key, value, allow_none=False)
        self.name = name
        self.targets = tuple(targets)
        self.terminate_on_success = bool(terminate_on_success)
        self._ranges = np.array([t.goal_range for t in self.targets])
        # the goal observation: goal / obs_scale per target, clipped (fused.finish_rows)
        self._obs_scales = np.array([t.obs_scale for t in self.targets])
        # the constants of score_rows
        self._index = np.array([t.index for t in self.targets], dtype=np.int64)
        self._tolerance = np.array([t.tolerance for t in self.targets])
        self._scale = np.array([t.scale for t in self.targets])
        self._weights = np.array([goal_weight, success_weight, ctrl_weight, failure_weight],
                                 dtype=np.float64)
        self._goal_scale = 1.0
        self._draw = self._draw_bounds()

    # the weights of the reward terms (module doc), fixed at construction
    goal_weight = property(lambda self: float(self._weights[0]), doc="Weight of reward_goal.")
    success_weight = property(lambda self: float(self._weights[1]),
                              doc="Weight of reward_success.")
    ctrl_weight = property(lambda self: float(self._weights[2]), doc="Weight of reward_ctrl.")
    failure_weight = property(lambda self: float(self._weights[3]),
                              doc="Weight of reward_failure.")

    @property
    def goal_scale(self) -> float:
        """Goals are drawn from ``goal_scale`` times the goal ranges (curriculum; 1 = as set;
        :meth:`set_goal_scale` changes it)."""
        return self._goal_scale

    def set_goal_scale(self, scale: float) -> None:
        """Draw goals from ``scale`` (in (0, 1]) times the goal ranges from the next reset on
        (a curriculum hook; goals given through ``reset(options={"goal": ...})`` are kept)."""
        if not (is_finite_real(scale) and 0.0 < scale <= 1.0):
            raise ValueError(f"goal scale must be a number in (0, 1] (got {scale!r})")
        self._goal_scale = float(scale)
        self._draw = self._draw_bounds()

    def _draw_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high - low) of the goal draw at the present ``goal_scale``."""
        ranges = self._ranges * self._goal_scale
        low = -ranges
        return low, ranges - low

    def sample_goals(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        # rng.uniform(low, high) on arrays, as NumPy computes it (low + (high - low) * u from
        # the same doubles), without its broadcasting path (about 30 us a call); each
        # generator fills its own row in place
        low, span = self._draw
        u = np.empty((len(rngs), low.size))
        for row, rng in zip(u, rngs, strict=True):
            rng.random(out=row)
        u *= span
        u += low
        return u

    def evaluate(self, pose, goal, ctrl, failed, grasped, scalar=None):
        coords = [np.asarray(pose[t.index], dtype=np.float64) for t in self.targets]
        goals = [np.asarray(g, dtype=np.float64) for g in goal]
        if len(goals) != len(coords):
            raise ValueError(f"goal must have {len(coords)} coordinates (got {len(goals)})")
        rest = (np.asarray(ctrl, dtype=np.float64), np.asarray(failed, dtype=bool),
                np.asarray(grasped, dtype=bool))
        shape = np.broadcast_shapes(*(a.shape for a in (*coords, *goals, *rest)))
        m = math.prod(shape)

        def flat(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(np.broadcast_to(a, shape)).reshape(m)

        terms = np.empty((len(GOAL_TERMS), m))
        success = np.empty(m, dtype=bool)
        reward = np.empty(m)
        ctrl_m, failed_m, grasped_m = (flat(a) for a in rest)
        score_rows(np.stack([flat(c) for c in coords], axis=1),
                   np.stack([flat(g) for g in goals], axis=1), ctrl_m, failed_m, grasped_m,
                   np.arange(m), np.arange(len(coords)), self._tolerance, self._scale,
                   self._weights, terms, success, reward)
        if scalar or (scalar is None and shape == ()):
            return tuple(terms[:, 0].tolist()), bool(success[0])
        return tuple(t.reshape(shape) for t in terms), success.reshape(shape)

    def __repr__(self) -> str:
        return f"GoalTask({self.name!r}, targets={[t.name for t in self.targets]})"


def make_task(task: str, **overrides: Any) -> Task:
    """Build a task from its YAML defaults and keyword overrides (``None`` = config value).

    Parameters
    ----------
    task : str
        ``"none"``, ``"reorient"``, ``"translate"`` or ``"pose"``.
    **overrides
        Any of :data:`TASK_KWARGS`; keywords a task does not use must be ``None``.

    Raises
    ------
    ValueError
        Unknown task, unknown key in the config file, keyword the task does not use, or a value
        out of range (the message names the keyword).
    """
    cfg = {k: v for k, v in load_task_config(task).items() if k != "max_episode_steps"}
    unknown = set(cfg) - set(TASK_KWARGS)
    if unknown:
        raise ValueError(f"configs/tasks/{task}.yaml: unknown keys {sorted(unknown)}")
    for key, value in overrides.items():
        if key not in TASK_KWARGS:
            raise TypeError(f"make_task() got an unexpected keyword {key!r}")
        if value is None:
            continue
        if key not in cfg:
            raise ValueError(f"task {task!r} does not use {key!r} (it takes {sorted(cfg)})")
        cfg[key] = value
    if task == "none":
        return NoTask()

    for key, value in cfg.items():  # the YAML values and the overrides, with the same checks
        check_keyword(key, value, allow_none=False)

    def number(key: str) -> float:
        return float(cfg[key])

    targets = []
    for name in TASK_TARGETS[task]:
        if name == "x":
            targets.append(
                Target(
                    "x",
                    POSE_X,
                    number("goal_x_range_mm") * 1e-3,
                    number("x_tolerance_mm") * 1e-3,
                    number("x_scale_mm") * 1e-3,
                    POSITION_SCALE,
                )
            )
        else:
            targets.append(
                Target(
                    "theta",
                    POSE_THETA,
                    math.radians(number("goal_theta_range_deg")),
                    math.radians(number("theta_tolerance_deg")),
                    math.radians(number("theta_scale_deg")),
                    ANGLE_SCALE,
                )
            )
    return GoalTask(
        task,
        tuple(targets),
        goal_weight=cfg["goal_weight"],
        success_weight=cfg["success_weight"],
        ctrl_weight=cfg["ctrl_weight"],
        failure_weight=cfg["failure_weight"],
        terminate_on_success=bool(cfg["terminate_on_success"]),
    )
