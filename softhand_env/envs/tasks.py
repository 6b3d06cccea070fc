"""Tasks: goal sampling, reward terms, success and termination (dm_control's Task role).

A task never touches the integrator; the environment hands it read-outs after every control
step. Every method is written with arithmetic operators only, so the same code evaluates one
environment (Python floats) or a batch (arrays of shape ``(N,)``) in
:class:`~softhand_env.envs.vector.SoftHandVectorEnv`.

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
``max_delta`` the action's set-point bound per step (rad), ``failed`` a physical termination.
``is_success`` = every ``|p_k - g_k| <= tolerance_k`` while the object is grasped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from softhand_env import kernel
from softhand_env.envs.observation import ANGLE_SCALE, OBS_BOUND, POSITION_SCALE
from softhand_env.envs.task_configs import TASK_TARGETS, load_task_config
from softhand_env.model import DN_1, DN_2, TH_1, TH_OBJ, X_OBJ
from softhand_env.params import is_finite_real

#: Constructor keywords that configure a goal task (``None`` in the env signature = task config).
TASK_KWARGS = (
    "goal_x_range_mm",
    "goal_theta_range_deg",
    "x_tolerance_mm",
    "theta_tolerance_deg",
    "x_scale_mm",
    "theta_scale_deg",
    "goal_weight",
    "success_weight",
    "ctrl_weight",
    "failure_weight",
    "terminate_on_success",
)

#: Reward term names of goal tasks, in summation order.
GOAL_TERMS = ("reward_goal", "reward_success", "reward_ctrl", "reward_failure")

#: Termination reasons (``info["termination_reason"]``), highest priority first.
REASONS = (
    "nonfinite_state",
    "constraint_violation",
    "overcompressed",
    "grasp_lost",
    "contact_past_base",
)
_DIVERGED = kernel.FLAG_NONFINITE | kernel.FLAG_CONSTRAINT


def step_flags(flags: Any, max_ch: Any, ch_limit: float) -> Any:
    """Kernel flags of a control step, with ``FLAG_CONSTRAINT`` added where the step's largest
    holonomic residual exceeded ``ch_limit``.

    The kernel compares |C^H| with the bound only when it completes the step; when another
    fatal flag (d_n out of range) stops integration first, a residual above the bound seen on
    the way would go unreported. The environments classify with this so that
    ``constraint_violation`` always means max |C^H| > ``ch_limit``, as documented.

    Parameters
    ----------
    flags : int or ndarray of int (N,)
    max_ch : float or ndarray (N,)
        Largest |C^H| (m) over the step (NaN compares False: NaN states carry their own flag).
    ch_limit : float
    """
    return flags | np.where(np.asarray(max_ch) > ch_limit, kernel.FLAG_CONSTRAINT, 0)


def base_ratio(yt: Any, a: float) -> Any:
    """How far the contact circles reach towards the fingertip bases (1 = at a base).

    The largest over both fingers of |tan theta_p| a_c / (a - d_n), with theta_p the contact
    angle (theta_1 - theta_obj, theta_2 + theta_obj) and a_c = sqrt(a^2 - (a - d_n)^2) the
    contact radius; a finger with d_n outside (0, a) counts 0 (no contact circle). Above 1 the
    closed-form energy over-predicts: by 0.3 % (force 1 %) at 1.03, 1 % (force 2 %) at 1.05
    (d_n = 5-8.5 mm, against :func:`softhand_env.contact.potential_energy_numeric`).

    Parameters
    ----------
    yt : sequence of 20 floats, or ndarray (20, N)
        State(s), coordinate axis first (see :func:`failure_state`).
    a : float
        Fingertip radius (m).
    """
    ratio = 0.0
    for i, sign in ((0, -1.0), (1, 1.0)):
        dn = np.asarray(yt[DN_1 + i])
        inside = (dn > 0.0) & (dn < a)
        d = np.where(inside, dn, 0.5 * a)  # keeps sqrt and division defined elsewhere
        tan_p = np.abs(np.tan(np.asarray(yt[TH_1 + i]) + sign * np.asarray(yt[TH_OBJ])))
        a_c = np.sqrt(a * a - (a - d) ** 2)
        ratio = np.maximum(ratio, np.where(inside, tan_p * a_c / (a - d), 0.0))
    return ratio


def failure_state(
    flags: Any, yt: Any, dn_limit: float, a: float = 0.0, base_limit: float = 1.0
) -> tuple[Any, Any, Any, Any]:
    """Classify the state after a control step.

    Parameters
    ----------
    flags : int or ndarray of int, shape (N,)
        Kernel status flags of the step (see :func:`step_flags`).
    yt : sequence of 20 floats, or ndarray (20, N)
        State after the step, coordinate axis first (``y.tolist()`` or ``Y.T``), so that
        ``yt[i]`` is a scalar for one environment and a column for a batch.
    dn_limit : float
        Normal deformation (m) at or above which the fingertip counts as over-compressed
        (default a/2, the fingertip model's validity limit).
    a : float
        Fingertip radius (m); needed when ``base_limit`` > 1.
    base_limit : float
        A state with the kernel's ``FLAG_BASE`` (a contact circle past its fingertip base)
        fails when :func:`base_ratio` exceeds this (1: as soon as the flag is set).

    Returns
    -------
    failed, grasped, diverged, overcompressed : bool or ndarray of bool
        ``failed`` = diverged | overcompressed | lost (d_n <= 0) | contact past the fingertip
        base; ``grasped`` = both d_n > 0 and the state valid.
    """
    dn1 = yt[DN_1]
    dn2 = yt[DN_2]
    diverged = (flags & _DIVERGED) != 0
    over = ((flags & kernel.FLAG_OVERCOMPRESSED) != 0) | (dn1 >= dn_limit) | (dn2 >= dn_limit)
    lost = ((flags & kernel.FLAG_LOST) != 0) | (dn1 <= 0.0) | (dn2 <= 0.0)
    base = (flags & kernel.FLAG_BASE) != 0
    if base_limit > 1.0 and np.any(base):  # rare: the ratio is computed only then
        base = base & (base_ratio(yt, a) > base_limit)
    failed = diverged | over | lost | base
    grasped = (dn1 > 0.0) & (dn2 > 0.0) & ((flags & _DIVERGED) == 0)
    return failed, grasped, diverged, over


def termination_reason(flags: int, y: np.ndarray, dn_limit: float) -> str:
    """Name of the highest-priority failure of one failed environment (see :data:`REASONS`)."""
    if flags & kernel.FLAG_NONFINITE:
        return REASONS[0]
    if flags & kernel.FLAG_CONSTRAINT:
        return REASONS[1]
    if flags & kernel.FLAG_OVERCOMPRESSED or max(y[DN_1], y[DN_2]) >= dn_limit:
        return REASONS[2]
    if flags & kernel.FLAG_LOST or min(y[DN_1], y[DN_2]) <= 0.0:
        return REASONS[3]
    return REASONS[4]  # the only failure left (failure_state): FLAG_BASE


@dataclass(frozen=True)
class Target:
    """One controlled object coordinate of a goal task (SI units).

    Attributes
    ----------
    name : str
        ``"x"`` (object x, m) or ``"theta"`` (object angle, rad).
    index : int
        Index of the coordinate in the state.
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
        return np.zeros(0)

    def goal_observation(self, goal: np.ndarray) -> np.ndarray:
        """The goal scaled for the observation, shape (..., goal_dim)."""
        return np.asarray(goal, dtype=np.float64)

    def goal_pose(self, y: np.ndarray, goal: np.ndarray) -> tuple[float, float] | None:
        """Object (x, theta) at the goal for drawing: targets from ``goal``, the rest from the
        state ``y`` (20,); None without a goal."""
        if not self.targets:
            return None
        pose = {"x": float(y[X_OBJ]), "theta": float(y[TH_OBJ])}
        for target, g in zip(self.targets, goal, strict=True):
            pose[target.name] = float(g)
        return pose["x"], pose["theta"]

    def evaluate(
        self, yt: np.ndarray, goal: tuple[Any, ...], ctrl: Any, failed: Any, grasped: Any
    ) -> tuple[tuple[Any, ...], Any]:
        """Reward terms (ordered as :attr:`terms`) and success for state(s) ``yt``.

        Parameters
        ----------
        yt : sequence of 20 floats, or ndarray (20, N)
            State after the step, coordinate axis first (see :func:`failure_state`).
        goal : tuple of float or of ndarray (N,)
            Goal coordinates (SI), one entry per target.
        ctrl : float or ndarray (N,)
            |u_t - u_{t-1}|^2 / max_delta^2 (dimensionless).
        failed, grasped : bool or ndarray of bool
            From :func:`failure_state`.
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
            if not (is_finite_real(value) and value >= 0):
                raise ValueError(f"{key} must be a finite number >= 0 (got {value!r})")
        self.name = name
        self.targets = tuple(targets)
        self.goal_weight = float(goal_weight)
        self.success_weight = float(success_weight)
        self.ctrl_weight = float(ctrl_weight)
        self.failure_weight = float(failure_weight)
        self.terminate_on_success = bool(terminate_on_success)
        self._ranges = np.array([t.goal_range for t in self.targets])
        self._obs_scales = np.array([t.obs_scale for t in self.targets])
        #: Goals are drawn from ``goal_scale`` times the goal ranges (curriculum; 1 = as set).
        self.goal_scale = 1.0

    def set_goal_scale(self, scale: float) -> None:
        """Draw goals from ``scale`` (in (0, 1]) times the goal ranges from the next reset on
        (a curriculum hook; goals given through ``reset(options={"goal": ...})`` are kept)."""
        if not (is_finite_real(scale) and 0.0 < scale <= 1.0):
            raise ValueError(f"goal scale must be a number in (0, 1] (got {scale!r})")
        self.goal_scale = float(scale)

    def sample_goal(self, rng: np.random.Generator) -> np.ndarray:
        ranges = self._ranges * self.goal_scale
        return rng.uniform(-ranges, ranges)

    def goal_observation(self, goal: np.ndarray) -> np.ndarray:
        scaled = np.asarray(goal, dtype=np.float64) / self._obs_scales
        return np.clip(scaled, -OBS_BOUND, OBS_BOUND)

    def evaluate(self, yt, goal, ctrl, failed, grasped):
        err = 0.0
        success = grasped
        for target, g in zip(self.targets, goal, strict=True):
            d = abs(yt[target.index] - g)
            err = err + d / target.scale
            success = success & (d <= target.tolerance)
        terms = (
            self.goal_weight * np.exp(-err),
            self.success_weight * success,
            0.0 - self.ctrl_weight * ctrl,
            0.0 - self.failure_weight * failed,
        )
        return terms, success

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

    def positive(key: str) -> float:
        value = cfg[key]
        if not (is_finite_real(value) and value > 0):
            raise ValueError(f"{key} must be a finite number > 0 (got {value!r})")
        return float(value)

    if not isinstance(cfg["terminate_on_success"], (bool, np.bool_)):
        raise ValueError(
            f"terminate_on_success must be True or False (got {cfg['terminate_on_success']!r})"
        )

    targets = []
    for name in TASK_TARGETS[task]:
        if name == "x":
            targets.append(
                Target(
                    "x",
                    X_OBJ,
                    positive("goal_x_range_mm") * 1e-3,
                    positive("x_tolerance_mm") * 1e-3,
                    positive("x_scale_mm") * 1e-3,
                    POSITION_SCALE,
                )
            )
        else:
            targets.append(
                Target(
                    "theta",
                    TH_OBJ,
                    math.radians(positive("goal_theta_range_deg")),
                    math.radians(positive("theta_tolerance_deg")),
                    math.radians(positive("theta_scale_deg")),
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
