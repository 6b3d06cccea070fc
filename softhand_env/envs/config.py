"""Validated, resolved environment configuration shared by the single and the vector env.

:func:`build_config` turns the keywords of :class:`~softhand_env.envs.SoftHandEnv`, collected
in an :class:`~softhand_env.envs.options.EnvOptions`, into an :class:`EnvConfig`: hand
parameters loaded from ``configs/hand/<hand>.yaml``, the task with its defaults from
``configs/tasks/<task>.yaml``, the action map, the observation layout, the control period in
substeps and the randomisation settings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from softhand_env.envs.actions import ActionMap
from softhand_env.envs.observation import ObservationLayout
from softhand_env.envs.options import EnvOptions
from softhand_env.envs.randomization import PRESET, Randomization
from softhand_env.envs.tasks import TASK_KWARGS, Task, make_task
from softhand_env.physics.params import HandParams, is_finite_real, load_hand_params
from softhand_env.physics.stability import warn_if_unstable

#: Upper bounds of the environment keywords, checked before anything is allocated or run
#: (with the other ranges, each ValueError names the keyword and its range): control period
#: (s), grasp phase (s), RK4 substeps per control step and per grasp phase (bounding the
#: hand's dt from below), frame size (px).
MAX_CONTROL_DT = 1.0
MAX_GRASP_DURATION = 10.0
MAX_SUBSTEPS = 100_000
MAX_GRASP_SUBSTEPS = 1_000_000
MAX_RENDER_SIZE = 4096
#: Largest ``setpoint_latency`` (control steps).
MAX_SETPOINT_LATENCY = 10

#: Allowed ``render_mode`` values.
RENDER_MODES = ("human", "rgb_array")


@dataclass(frozen=True)
class EnvConfig:
    """Everything an environment needs besides its state (see :func:`build_config`).

    Attributes
    ----------
    task : Task
    params : HandParams
        Nominal hand parameters (SI).
    actions : ActionMap
    layout : ObservationLayout
    n_substeps : int
        RK4 substeps per control step.
    dt : float
        Control period (s) = n_substeps * params.dt.
    grasp_setpoint : ndarray, shape (2,)
        Grasp set-points (rad); also the first set-points of an episode.
    n_grasp : int
        Grasp phase in substeps.
    reset_noise : float
        Half-width (rad) of uniform noise on the grasp set-points.
    randomization : Randomization
    setpoint_latency : int
        Largest set-point latency in control steps (0: none); each episode draws its latency
        uniformly from 0..setpoint_latency.
    dn_limit : float
        Over-compression limit on d_n (m).
    ch_limit : float
        Divergence limit on |C^H| (m).
    base_limit : float
        1 + ``base_tolerance``: a contact past its fingertip base fails when it reaches past
        the base by more than this (:func:`softhand_env.physics.contact.beyond_base`).
    terminate_on_slip : bool
        A control step whose contact needs more friction than ``mu`` (``slip``) or pulls
        (``tension``) ends the episode (False: only reported in ``info``).
    render_mode : str or None
    render_size : (int, int)
        Frame (width, height) in pixels.
    """

    task: Task
    params: HandParams
    actions: ActionMap
    layout: ObservationLayout
    n_substeps: int
    dt: float
    grasp_setpoint: np.ndarray
    n_grasp: int
    reset_noise: float
    randomization: Randomization
    setpoint_latency: int
    dn_limit: float
    ch_limit: float
    base_limit: float
    terminate_on_slip: bool
    render_mode: str | None
    render_size: tuple[int, int]


def _pair(name: str, value: Sequence[float]) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair of numbers (got {value!r})") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise ValueError(f"{name} must be finite (got {value!r})")
    return a, b


def _number(name: str, value: Any, low: float, high: float = math.inf) -> float:
    if not (is_finite_real(value) and low <= value <= high):
        raise ValueError(f"{name} must be a number in [{low:g}, {high:g}] (got {value!r})")
    return float(value)


def _tolerance(name: str, value: Any) -> float:
    """A number >= 0; ``math.inf`` allowed (switches the check off)."""
    infinite = isinstance(value, (float, np.floating)) and value == math.inf
    if not (infinite or is_finite_real(value)) or not value >= 0:
        raise ValueError(f"{name} must be a number in [0, inf] (got {value!r})")
    return float(value)


def _flag(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False (got {value!r})")
    return bool(value)


def build_config(options: EnvOptions) -> EnvConfig:
    """Validate the environment keywords and resolve them into an :class:`EnvConfig`.

    Raises ``ValueError`` naming the keyword (randomisation ranges whose extremes leave RK4's
    stable region or the valid range of a parameter included); warns (``RuntimeWarning``)
    if the hand itself is beyond RK4's stability limit at its ``dt``
    (:func:`~softhand_env.physics.stability.warn_if_unstable`).
    """
    o = options
    task_kw = {k: getattr(o, k) for k in TASK_KWARGS}
    rand_kw = {k: getattr(o, k) for k in PRESET}
    hand_overrides = o.hand_overrides
    if hand_overrides is not None and not isinstance(hand_overrides, Mapping):
        raise ValueError(
            f"hand_overrides must be None or a dict of HandParams fields (got {hand_overrides!r})"
        )
    params = load_hand_params(o.hand, **dict(hand_overrides or {}))
    joint_range = _pair("joint_range_deg", o.joint_range_deg)
    grasp = _pair("grasp_setpoint_deg", o.grasp_setpoint_deg)
    if not all(joint_range[0] <= g <= joint_range[1] for g in grasp):
        raise ValueError(
            f"grasp_setpoint_deg must lie within joint_range_deg {list(joint_range)} "
            f"(got {o.grasp_setpoint_deg!r})"
        )
    control_dt = _number("control_dt", o.control_dt, 0.0, MAX_CONTROL_DT)
    if control_dt / params.dt > MAX_SUBSTEPS:
        raise ValueError(
            f"control_dt / dt = {control_dt / params.dt:.3g} substeps per control step is more "
            f"than {MAX_SUBSTEPS:,}: raise the hand's dt or lower control_dt"
        )
    n_substeps = round(control_dt / params.dt)
    if n_substeps < 1 or abs(n_substeps * params.dt - control_dt) > 1e-9:
        raise ValueError(
            f"control_dt must be a positive multiple of the RK4 substep {params.dt:g} s "
            f"(got {o.control_dt!r})"
        )
    grasp_duration = _number("grasp_duration", o.grasp_duration, 0.0, MAX_GRASP_DURATION)
    if grasp_duration / params.dt > MAX_GRASP_SUBSTEPS:
        raise ValueError(
            f"grasp_duration / dt = {grasp_duration / params.dt:.3g} substeps is more than "
            f"{MAX_GRASP_SUBSTEPS:,}: raise the hand's dt or shorten grasp_duration"
        )
    n_grasp = round(grasp_duration / params.dt)
    if abs(n_grasp * params.dt - grasp_duration) > 1e-9:
        raise ValueError(
            f"grasp_duration must be a multiple of the RK4 substep {params.dt:g} s "
            f"(got {o.grasp_duration!r})"
        )
    if o.render_mode is not None and (
        not isinstance(o.render_mode, str) or o.render_mode not in RENDER_MODES
    ):
        raise ValueError(
            f"render_mode must be None or one of {RENDER_MODES} (got {o.render_mode!r})"
        )
    for name, value in (("render_width", o.render_width), ("render_height", o.render_height)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, np.integer))
            or not 16 <= value <= MAX_RENDER_SIZE
        ):
            raise ValueError(f"{name} must be an int in [16, {MAX_RENDER_SIZE}] (got {value!r})")
    latency = o.setpoint_latency
    if (
        isinstance(latency, (bool, np.bool_))
        or not isinstance(latency, (int, np.integer))
        or not 0 <= latency <= MAX_SETPOINT_LATENCY
    ):
        raise ValueError(
            f"setpoint_latency must be an int in [0, {MAX_SETPOINT_LATENCY}] (got {latency!r})"
        )
    task_obj = make_task(o.task, **task_kw)
    randomization = Randomization.resolve(_flag("randomize", o.randomize), **rand_kw)
    randomization.check_ranges(params)
    warn_if_unstable(params, stacklevel=3)
    return EnvConfig(
        task=task_obj,
        params=params,
        actions=ActionMap(
            o.action_mode,
            _flag("normalize_action", o.normalize_action),
            _number("max_delta_deg", o.max_delta_deg, 1e-3, 30.0),
            joint_range,
        ),
        layout=ObservationLayout(
            o.obs_mode, o.history_len, tuple(t.name for t in task_obj.targets)
        ),
        n_substeps=n_substeps,
        dt=n_substeps * params.dt,
        grasp_setpoint=np.radians(grasp),
        n_grasp=n_grasp,
        reset_noise=math.radians(_number("reset_noise_deg", o.reset_noise_deg, 0.0, 10.0)),
        randomization=randomization,
        setpoint_latency=int(latency),
        dn_limit=_number("overcompression_ratio", o.overcompression_ratio, 1e-3, 1.0) * params.a,
        ch_limit=_number("ch_limit", o.ch_limit, 1e-12, 1.0),
        base_limit=1.0 + _tolerance("base_tolerance", o.base_tolerance),
        terminate_on_slip=_flag("terminate_on_slip", o.terminate_on_slip),
        render_mode=o.render_mode,
        render_size=(int(o.render_width), int(o.render_height)),
    )
