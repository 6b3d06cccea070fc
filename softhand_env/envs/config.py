"""Validated, resolved environment configuration shared by the single and the vector env.

:func:`build_config` turns the keywords of :class:`~softhand_env.envs.SoftHandEnv`, collected
in an :class:`~softhand_env.envs.options.EnvOptions`, into an :class:`EnvConfig`: hand
parameters loaded from ``configs/hand/<hand>.yaml``, the task with its defaults from
``configs/tasks/<task>.yaml``, the action map, the observation layout, the control period in
substeps and the randomisation settings.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from softhand_env.envs.actions import ActionMap
from softhand_env.envs.observation import ObservationLayout
from softhand_env.envs.options import KEYWORDS, EnvOptions, check_options
from softhand_env.envs.randomization import PRESET, Randomization
from softhand_env.envs.sensors import SensorSpec, load_sensor_spec
from softhand_env.envs.tasks import TASK_KWARGS, Task, make_task
from softhand_env.physics.params import HandParams, load_hand_params
from softhand_env.physics.stability import warn_if_unstable

#: Upper bounds of the substeps (control period and grasp phase over the hand's RK4 substep),
#: checked with the keyword ranges before anything is allocated or run (each ValueError names
#: the keywords): they bound the hand's dt from below.
MAX_SUBSTEPS = 100_000
MAX_GRASP_SUBSTEPS = 1_000_000
#: Stair length of a set-point ramp (``setpoint_ramp_ms``), s.
RAMP_STAIR_S = 0.01

#: Allowed ``render_mode`` values.
RENDER_MODES = KEYWORDS["render_mode"].choices


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
    sensors : SensorSpec
        The sensor model (``sensor_model``; :mod:`softhand_env.envs.sensors`).
    rand_sensors : bool
        Each episode draws its torque-sensor gains.
    substep_limits : bool
        The hard limits (``dn_limit``, ``base_limit``, ``ch_limit``) are tested on every RK4
        substep and a step ends at the first substep beyond one (False: on the state at the
        end of the control step).
    slip_window : int or None
        Slip and tension are judged on windows of this many RK4 substeps, tiled from the end
        of the grasp phase (None: on each control step).
    setpoint_ramp : int
        The set-points of a control step move from the previous ones to the new command over
        this many RK4 substeps (``setpoint_ramp_ms``; 0: they jump at the step's start), in
        stairs of ``ramp_stair`` substeps: stair k (0-based) holds the previous set-points
        plus (k + 1) / K of the change, K = ``setpoint_ramp / ramp_stair``.
    ramp_stair : int
        Stair length in RK4 substeps (:data:`RAMP_STAIR_S`).
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
    sensors: SensorSpec
    rand_sensors: bool
    render_mode: str | None
    render_size: tuple[int, int]
    substep_limits: bool = False
    slip_window: int | None = None
    setpoint_ramp: int = 0
    ramp_stair: int = 0


def _pair(value: Sequence[float]) -> tuple[float, float]:
    """A checked pair keyword (:func:`~softhand_env.envs.options.check_options`) as floats."""
    a, b = (float(v) for v in value)
    return a, b


def build_config(options: EnvOptions) -> EnvConfig:
    """Validate the environment keywords and resolve them into an :class:`EnvConfig`.

    First every keyword's own check (:func:`~softhand_env.envs.options.check_options`: its
    type and range, from :data:`~softhand_env.envs.options.KEYWORDS`), then the checks that
    relate keywords or need the hand (here and in the modules that resolve them). Raises
    ``ValueError`` naming the keyword (randomisation ranges whose extremes leave RK4's
    stable region or the valid range of a parameter included); warns (``RuntimeWarning``)
    if the hand itself is beyond RK4's stability limit at its ``dt``
    (:func:`~softhand_env.physics.stability.warn_if_unstable`).
    """
    o = options
    check_options(o)
    task_kw = {k: getattr(o, k) for k in TASK_KWARGS}
    rand_kw = {k: getattr(o, k) for k in PRESET}
    params = load_hand_params(o.hand, **dict(o.hand_overrides or {}))
    joint_range = _pair(o.joint_range_deg)
    grasp = _pair(o.grasp_setpoint_deg)
    if not all(joint_range[0] <= g <= joint_range[1] for g in grasp):
        raise ValueError(
            f"grasp_setpoint_deg must lie within joint_range_deg {list(joint_range)} "
            f"(got {o.grasp_setpoint_deg!r})"
        )
    control_dt = float(o.control_dt)
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
    grasp_duration = float(o.grasp_duration)
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
    slip_window = None
    if o.slip_window_ms is not None:
        slip_window = round(float(o.slip_window_ms) * 1e-3 / params.dt)
        if abs(slip_window * params.dt - float(o.slip_window_ms) * 1e-3) > 1e-9:
            raise ValueError(
                f"slip_window_ms must be a multiple of the RK4 substep {params.dt * 1e3:g} ms "
                f"(got {o.slip_window_ms!r})"
            )
    setpoint_ramp, ramp_stair = _ramp(o, params.dt, n_substeps, slip_window)
    task_obj = make_task(o.task, **task_kw)
    randomization = Randomization.resolve(bool(o.randomize), **rand_kw)
    randomization.check_ranges(params)
    warn_if_unstable(params, stacklevel=3)
    sensors = load_sensor_spec(o.sensor_model)
    if o.rand_sensors and sensors.ideal:
        raise ValueError("rand_sensors=True draws the gains of a sensor model: it needs "
                         "sensor_model='realistic' (got sensor_model='ideal')")
    if o.sensor_noise_scale != 1.0:
        if sensors.ideal:
            raise ValueError("sensor_noise_scale scales the errors of a sensor model: it needs "
                             "sensor_model='realistic' (got sensor_model='ideal')")
        sensors = sensors.scaled(float(o.sensor_noise_scale))
    return EnvConfig(
        task=task_obj,
        params=params,
        actions=ActionMap(o.action_mode, bool(o.normalize_action), float(o.max_delta_deg),
                          joint_range),
        layout=ObservationLayout(
            o.obs_mode, o.history_len, tuple(t.name for t in task_obj.targets),
            onset=bool(o.onset_obs),
        ),
        n_substeps=n_substeps,
        dt=n_substeps * params.dt,
        grasp_setpoint=np.radians(grasp),
        n_grasp=n_grasp,
        reset_noise=math.radians(float(o.reset_noise_deg)),
        randomization=randomization,
        setpoint_latency=int(o.setpoint_latency),
        dn_limit=float(o.overcompression_ratio) * params.a,
        ch_limit=float(o.ch_limit),
        base_limit=1.0 + float(o.base_tolerance),
        terminate_on_slip=bool(o.terminate_on_slip),
        sensors=sensors,
        rand_sensors=bool(o.rand_sensors),
        render_mode=o.render_mode,
        render_size=(int(o.render_width), int(o.render_height)),
        substep_limits=bool(o.substep_limits),
        slip_window=slip_window,
        setpoint_ramp=setpoint_ramp,
        ramp_stair=ramp_stair,
    )


def _ramp(o: EnvOptions, dt: float, n_substeps: int,
          slip_window: int | None) -> tuple[int, int]:
    """``setpoint_ramp_ms`` as (ramp, stair) in RK4 substeps of ``dt`` (s), checked against the
    control step of ``n_substeps`` substeps and the slip windows (``ValueError``)."""
    ramp_s = float(o.setpoint_ramp_ms) * 1e-3
    if ramp_s == 0.0:
        return 0, 0
    stairs = round(ramp_s / RAMP_STAIR_S)
    if abs(stairs * RAMP_STAIR_S - ramp_s) > 1e-9:
        raise ValueError(f"setpoint_ramp_ms must be a multiple of {RAMP_STAIR_S * 1e3:g} ms "
                         f"(got {o.setpoint_ramp_ms!r})")
    stair = round(RAMP_STAIR_S / dt)
    if abs(stair * dt - RAMP_STAIR_S) > 1e-12:
        raise ValueError(f"setpoint_ramp_ms needs an RK4 substep that divides "
                         f"{RAMP_STAIR_S * 1e3:g} ms (the hand's dt is {dt:g} s)")
    if stairs * stair > n_substeps:
        raise ValueError(f"setpoint_ramp_ms must be at most control_dt = {n_substeps * dt * 1e3:g}"
                         f" ms (got {o.setpoint_ramp_ms!r})")
    if slip_window is None:
        raise ValueError("setpoint_ramp_ms steps the physics stair by stair, which needs slip "
                         "and tension judged on windows of physical time: set slip_window_ms "
                         "(the -v1 ids do)")
    return stairs * stair, stair
