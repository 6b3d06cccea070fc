"""The keywords of the soft-hand environments as one explicit, documented record.

:class:`EnvOptions` holds every ``gym.make(id, **kwargs)`` keyword of
:class:`~softhand_env.envs.SoftHandEnv` (and of the vector env) with its default;
:func:`~softhand_env.envs.config.build_config` validates it and resolves it into an
:class:`~softhand_env.envs.config.EnvConfig`. ``SoftHandEnv.__init__`` spells the same keywords
out in its signature (its manual's Arguments table); a test keeps the two identical.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class EnvOptions:
    """Keywords of the soft-hand environments (see the Arguments table of ``SoftHandEnv``).

    ``None`` for a task keyword means the value in ``configs/tasks/<task>.yaml``; ``None`` for
    a ``rand_*`` keyword or ``obs_noise`` means the ``randomize`` preset. Values are checked by
    :func:`~softhand_env.envs.config.build_config` (``ValueError`` naming the keyword); an
    unknown keyword raises ``TypeError`` here.

    Attributes
    ----------
    task : str
        ``'none'``, ``'reorient'``, ``'translate'`` or ``'pose'``
    action_mode : str
        ``'delta'`` (set-point change) or ``'absolute'``
    normalize_action : bool
        False (absolute only): action = set-points in rad
    max_delta_deg : float
        largest set-point change per step (deg); ctrl-cost unit
    joint_range_deg : tuple[float, float]
        set-point limits (deg)
    control_dt : float
        control period (s), a multiple of the 0.1 ms substep
    obs_mode : str
        ``'proprio'`` or ``'proprio_tactile'`` (adds d_n, d_t)
    history_len : int
        number of observation frames, newest first
    grasp_setpoint_deg : tuple[float, float]
        grasp set-points (deg), first set-points
    grasp_duration : float
        grasp phase in reset (s); 0 = point-contact start
    reset_noise_deg : float
        half-width of uniform noise on the grasp set-points
    hand : str
        hand config name in ``configs/hand/`` or a YAML path
    hand_overrides : dict[str, Any] | None
        HandParams fields (SI) replacing config values
    overcompression_ratio : float
        terminate when d_n >= ratio * a
    ch_limit : float
        terminate when a holonomic residual exceeds this (m)
    base_tolerance : float
        allowed overshoot of tan theta_p past the base (inf: off)
    terminate_on_slip : bool
        end the episode on slip or tension (False: report only)
    randomize : bool
        preset for every ``rand_*`` / ``obs_noise`` left at None
    rand_width : float | None
        object width, relative half-width (preset 0.03)
    rand_mass : float | None
        object mass, relative half-width (preset 0.2)
    rand_inertia : float | None
        object inertia, relative half-width (preset 0.2)
    rand_stiffness : float | None
        Young's modulus E, relative half-width (preset 0.1)
    rand_damping : float | None
        c_n and c_t, relative half-width (preset 0.2)
    rand_gains : float | None
        Kp, Kd, Ki, relative half-width (preset 0.1)
    rand_friction : float | None
        friction coefficient mu, relative half-width (preset 0.2)
    obs_noise : float | None
        observation noise std, scaled units (preset 0.01)
    setpoint_latency : int
        largest set-point latency (steps), drawn 0..this
    goal_x_range_mm : float | None
        x* ~ U(-r, r) (mm)
    goal_theta_range_deg : float | None
        theta* ~ U(-r, r) (deg)
    x_tolerance_mm : float | None
        success tolerance on x (mm)
    theta_tolerance_deg : float | None
        success tolerance on theta (deg)
    x_scale_mm : float | None
        error scale of reward_goal for x (mm)
    theta_scale_deg : float | None
        error scale of reward_goal for theta (deg)
    goal_weight : float | None
        weight of reward_goal
    success_weight : float | None
        weight of reward_success
    ctrl_weight : float | None
        weight of reward_ctrl
    failure_weight : float | None
        weight of reward_failure
    terminate_on_success : bool | None
        end the episode on success
    render_mode : str | None
        None, ``'rgb_array'`` or ``'human'``
    render_width : int
        frame width (px)
    render_height : int
        frame height (px)
    """

    task: str = 'none'
    action_mode: str = 'delta'
    normalize_action: bool = True
    max_delta_deg: float = 1.0
    joint_range_deg: tuple[float, float] = (-30.0, 30.0)
    control_dt: float = 0.02
    obs_mode: str = 'proprio'
    history_len: int = 1
    grasp_setpoint_deg: tuple[float, float] = (6.0, 6.0)
    grasp_duration: float = 0.5
    reset_noise_deg: float = 0.0
    hand: str = 'paper_ch5'
    hand_overrides: dict[str, Any] | None = None
    overcompression_ratio: float = 0.5
    ch_limit: float = 0.001
    base_tolerance: float = 0.05
    terminate_on_slip: bool = True
    randomize: bool = False
    rand_width: float | None = None
    rand_mass: float | None = None
    rand_inertia: float | None = None
    rand_stiffness: float | None = None
    rand_damping: float | None = None
    rand_gains: float | None = None
    rand_friction: float | None = None
    obs_noise: float | None = None
    setpoint_latency: int = 0
    goal_x_range_mm: float | None = None
    goal_theta_range_deg: float | None = None
    x_tolerance_mm: float | None = None
    theta_tolerance_deg: float | None = None
    x_scale_mm: float | None = None
    theta_scale_deg: float | None = None
    goal_weight: float | None = None
    success_weight: float | None = None
    ctrl_weight: float | None = None
    failure_weight: float | None = None
    terminate_on_success: bool | None = None
    render_mode: str | None = None
    render_width: int = 480
    render_height: int = 480

    def as_dict(self) -> dict[str, Any]:
        """The keywords and their values, in signature order."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
