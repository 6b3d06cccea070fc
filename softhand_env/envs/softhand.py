"""The single soft-hand environment (:class:`SoftHandEnv`); its docstring is the user manual."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from softhand_env.envs.actions import action_array
from softhand_env.envs.config import RENDER_MODES, build_config
from softhand_env.envs.observation import observe_rows
from softhand_env.envs.options import KEYWORDS, EnvOptions, arguments_table, check_seed
from softhand_env.envs.sensors import SensorSpec
from softhand_env.envs.transition import EpisodeBatch, reset_goal
from softhand_env.physics.hand import HandPhysics

if TYPE_CHECKING:
    from softhand_env.envs.rendering import HumanViewer, SceneRenderer

_ONE = np.ones(1, dtype=bool)


class SoftHandEnv(gym.Env):
    r"""Blind manipulation with a soft-fingered, two-joint hand (chapter-5 dynamic model).

    ## Description

    Two fingers, one rotary joint each, with hemispherical soft fingertips hold a rigid planar
    object between them (finger 1 on the right, finger 2 on the left; theta_i > 0 turns finger
    i inward; theta_obj > 0 is counter-clockwise). The fingertips are virtual-spring contacts
    (normal deformation d_n, tangential d_t) with rolling constraints, integrated by RK4 at
    0.1 ms with constraint stabilisation; a PID loop in every substep makes each finger track
    its set-point. The agent commands the two set-points once per control period
    (``control_dt``, default 20 ms) and must move the object **blind**: it observes only its
    own joints (angles, velocities, set-points, PID torques) and, optionally, the fingertip
    deformations, never the object's pose. Information about the object that reaches the
    joints through the contact forces over time is sensing and allowed. The object's pose is
    in ``info`` for evaluation only.

    Moving both fingers the same way translates *and* rotates the object (rolling couples
    x and theta, an S-shaped path); reaching x and theta independently needs non-holonomic
    (rolling) manoeuvres. Squeezing is limited: from the default grasp (6 deg, 6 deg; d_n
    about 7 mm) a couple of degrees more on both fingers exceeds the fingertip model's
    validity limit d_n = a/2 = 10 mm, and opening them drops the object.

    Registered ids (defaults of the task keywords in ``configs/tasks/<task>.yaml``):

    | id                      | task        | goal                        | max_episode_steps |
    |-------------------------|-------------|-----------------------------|-------------------|
    | `SoftHand-v0`           | `none`      | none, reward 0 (replay)     | 500 (10 s)        |
    | `SoftHandReorient-v0`   | `reorient`  | theta_obj to theta*         | 250 (5 s)         |
    | `SoftHandTranslate-v0`  | `translate` | x_obj to x*                 | 250 (5 s)         |
    | `SoftHandPose-v0`       | `pose`      | x_obj to x* and theta* both | 400 (8 s)         |
    | `SoftHandReorientRandom-v0` | `reorient` | as Reorient, randomised | 250 (5 s)         |
    | `SoftHandTranslateRandom-v0` | `translate` | as Translate, randomised | 250 (5 s)        |
    | `SoftHandPoseRandom-v0` | `pose`      | as Pose, randomised         | 400 (8 s)         |

    Each id also exists as ``-v1`` (``SoftHandPose-v1``, ...): the same task with the
    keywords of :data:`softhand_env.envs.V1_KWARGS` (realistic sensors,
    ``sensor_model="realistic"``) and, for the ``Random`` ids, of
    :data:`softhand_env.envs.V1_RANDOM_KWARGS` (each episode draws its torque-sensor gains,
    ``rand_sensors=True``). The ``-v0`` ids keep their original semantics (exact read-outs;
    the shipped models were trained on them); see Version History.
    :func:`softhand_env.envs.registered_kwargs` gives the keywords of any id.

    The ``Random`` ids are the top rung of the randomisation ladder (keywords in
    :data:`softhand_env.envs.RANDOM_KWARGS`, each overridable): object width +-10 %, mass and
    inertia +-50 %, Young's modulus +-30 %, damping +-30 %, PID gains +-30 %, observation
    noise 0.01, a set-point latency of 0 or 1 control steps per episode, and the RK4 substep
    halved to 0.05 ms (``hand_overrides={"dt": 5e-5}``: at 0.1 ms the lightest, softest,
    least damped corner of these ranges puts the finger mode beyond RK4's stability limit;
    at 0.05 ms every corner is stable, the gains up to +-40 %). Passing your own
    ``hand_overrides`` replaces that dict: keep ``"dt": 5e-5`` in it. Post-grasp d_n over
    these ranges: 4.9-9.7 mm (grasp phase at every corner of the box; tested), below the
    10 mm limit a/2; the wider objects (about a third of the draws) start beyond the 8 mm up
    to which the fingertip model was validated by the compression tests.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``; one entry per finger, mapped to the set-points
    (theta_1^d, theta_2^d) that the PID tracks during the next control period:

    | index | `action_mode="delta"` (default)        | `action_mode="absolute"`        | unit |
    |-------|----------------------------------------|---------------------------------|------|
    | 0     | change of theta_1^d, x `max_delta_deg` | theta_1^d over `joint_range_deg`| rad  |
    | 1     | change of theta_2^d, x `max_delta_deg` | theta_2^d over `joint_range_deg`| rad  |

    With ``action_mode="absolute", normalize_action=False`` the action space is
    ``Box(low, high, (2,), float32)`` with the joint range in rad and the action *is* the
    set-point pair in radians (used by scripted replay; the float64 values passed are used
    unrounded). With ``setpoint_latency`` = K > 0 each episode draws a latency L in 0..K
    (uniform): the set-points commanded by an action take effect L control steps later, the
    earlier ones staying applied meanwhile (delta actions and the control cost refer to the
    commanded set-points; the physics, the observation's set-point entries and
    ``info["setpoint"]`` show the applied ones). Out-of-range actions are clipped (to
    [-1, 1], then set-points to the joint range); NaN or inf raise ``ValueError``, as does a
    wrong shape; anything but real numbers
    (bool, int, float: complex, strings, dates, objects, masked arrays) raises ``TypeError``.

    ## Observation Space

    ``Box(-100, 100, (n,), float32)`` (entries clipped to the bounds, reached only by torque
    spikes above 1000 N m or a diverging state); ``history_len`` frames (newest first), then
    (``onset_obs=True``) the grasp-onset angles, then the goal:

    | index   | name                 | quantity                          | unit  | divided by |
    |---------|----------------------|-----------------------------------|-------|------------|
    | 0, 1    | theta_1, theta_2     | joint angles                      | rad   | 30 deg     |
    | 2, 3    | omega_1, omega_2     | joint velocities                  | rad/s | 5          |
    | 4, 5    | setpoint_1, _2       | current set-points                | rad   | 30 deg     |
    | 6, 7    | torque_1, torque_2   | PID torques (Eq 5.42)             | N m   | 10         |
    | 8, 9    | d_n1, d_n2           | normal deformations (tactile)     | m     | 10 mm      |
    | 10, 11  | d_t1, d_t2           | tangential deformations (tactile) | m     | 1 mm       |
    | frames  | onset_theta_1, _2    | joint angles at the grasp's start | rad   | 30 deg     |
    | end     | goal_x, goal_theta   | target x / theta (goal tasks)     | m/rad | 30 mm/30 deg|

    Entries 8-11 exist only with ``obs_mode="proprio_tactile"`` (frame size 12, else 8). The
    two grasp-onset entries (after the frames, ``onset_obs=True``) are the joint angles of the
    grasp phase's first state, where the fingertips touch the object undeformed (the paper's
    point-contact start, 0 for its object width), read once per episode through the encoder
    model and constant for the episode: what a hand that closed on the object itself knows of
    where contact began. They tell the object's width, and with the present angles how far
    the fingertips are compressed, which joint angles and torques alone leave open on the
    ``Random`` ids (randomised width and stiffness). The
    frame is a function of the finger part of the state, the set-points and the PID gains
    only (:func:`softhand_env.envs.observation.observe_rows`), read through the sensor model
    ``sensor_model`` (:mod:`softhand_env.envs.sensors`, values in
    ``configs/sensors/realistic.yaml``, rationale in ``docs/sensors.md``): ``"ideal"`` (the
    ``-v0`` default) observes the exact read-outs; ``"realistic"`` (the ``-v1`` default)
    observes 12-bit encoder angles (0.088 deg counts, 0.03 deg noise), the velocity as the
    difference of two encoder readings over the control period, motor-current torques
    (0.2 N m noise, a per-episode offset of std 0.1 N m, with ``rand_sensors=True`` a
    per-episode gain within +-10 %) and, with tactile entries, deformations with 0.05 mm
    noise; ``sensor_noise_scale`` multiplies its noises and torque offset (0: quantisation
    only). The set-point entries are exact. The scaling stays the same, so entries stay
    O(1). ``obs_noise`` adds Gaussian noise of that standard deviation (scaled units) to each
    frame, after the sensor model (0 unless set or ``randomize=True``; 0.01 on the ``Random``
    ids of both versions). ``info`` keeps the true values, ``env.unwrapped.physics`` the
    true joint read-outs; ``env.unwrapped.sensors`` is the sensor model
    (:class:`~softhand_env.envs.sensors.SensorSpec`) and ``env.unwrapped.sensor_calibration``
    the episode's torque offsets and gains.

    ## Rewards

    ``SoftHand-v0`` (task ``none``): always 0, no reward terms. Goal tasks: the sum of four
    named terms, each copied to ``info``:

    - ``reward_goal = goal_weight * exp(-e)``, e = sum over targets of |p - p*| / scale
      (scale ``x_scale_mm``, ``theta_scale_deg``); in (0, goal_weight], so surviving is never
      worse than dropping the object.
    - ``reward_success = success_weight * is_success``; ``is_success`` = every target within
      its tolerance (``x_tolerance_mm``, ``theta_tolerance_deg``) while grasped.
    - ``reward_ctrl = -ctrl_weight * |u_t - u_{t-1}|^2 / max_delta^2`` (set-points in rad,
      ``max_delta`` = ``max_delta_deg`` in rad, in every action mode).
    - ``reward_failure = -failure_weight`` on the step that ends the episode by a failure.

    ## Starting State

    The paper's parallel point-contact state (fingers parallel, touching the object at one
    point, everything at rest; Sec 5.5.1), then a grasp phase inside ``reset``: the set-points
    ``grasp_setpoint_deg`` (plus uniform noise of half-width ``reset_noise_deg``) are held for
    ``grasp_duration`` seconds, so episodes start with the object held (d_n about 7 mm).
    ``grasp_duration=0`` starts at the point-contact state itself (paper replay). The first
    set-points of the episode are the grasp set-points. The post-grasp state is cached when
    nothing is randomised. ``reset(seed=...)`` seeds ``np_random``, which draws (in order) the
    randomised parameters (``rand_*``, relative half-widths of object width, mass, inertia,
    Young's modulus, damping, PID gains; ``randomize=True`` applies a preset), the grasp
    noise, the goal (uniform within ``goal_x_range_mm`` / ``goal_theta_range_deg``), the
    friction coefficient (``rand_friction``), the set-point latency (only with
    ``setpoint_latency`` > 0), the sensor calibration (``sensor_model="realistic"``: torque
    offsets, then gains with ``rand_sensors=True``), the sensor noise of the first reading
    and the observation noise; a randomised draw whose grasp phase fails is redrawn (up to
    10 times). Randomisation ranges whose extremes would make RK4 unstable at the hand's
    substep (e.g. ``rand_gains`` above 0.137 with the other presets at 0.1 ms) raise
    ``ValueError`` at construction, naming the keyword and the limit; a hand that is itself
    beyond the limit (``hand_overrides``) gets a ``RuntimeWarning``.
    ``reset`` raises :class:`~softhand_env.physics.PhysicsError` if the grasp phase itself ends
    in one of the failures of Episode End (e.g. ``grasp_setpoint_deg=(12, 12)`` over-compresses
    the fingertips; every draw failing with randomisation): that configuration cannot start
    an episode. ``reset(options={"goal": g})`` sets the goal (SI units) instead; it must lie
    within the task's goal range (``ValueError`` otherwise). ``options`` must be None or a
    dict (``TypeError``) whose only key is ``"goal"`` (``ValueError`` listing the allowed keys).

    Goal curriculum: ``env.unwrapped.task.set_goal_scale(s)``, s in (0, 1], draws the goals of
    the following resets from s times the goal ranges (the same uniform draws, scaled; s = 1
    is the default); the native vector env's N environments share the task, so one call
    scales them all, autoresets included. Stable-Baselines3: ``agents.sb3.curriculum``
    (``set_goal_scale(venv, s)`` on a ``DummyVecEnv`` or the native ``NativeVecEnv``,
    ``GoalCurriculumCallback``). It is not a reset option, which would reach explicit resets
    only, not the autoresets of vector envs.

    ## Episode End

    Termination (``terminated=True``, reason in ``info["termination_reason"]``) when the state
    leaves the model's validity; if several apply, the first of this list is reported:

    - ``nonfinite_state``: NaN/inf in the state; it is rolled back to the last finite one, so
      observations and info stay finite.
    - ``constraint_violation``: max |C^H| over the step > ``ch_limit``.
    - ``overcompressed``: a d_n >= ``overcompression_ratio`` * a (the fingertip model's
      validity limit a/2 by default).
    - ``grasp_lost``: a d_n <= 0 (the bilateral contact would pull).
    - ``contact_past_base``: a contact circle passed its fingertip base, beyond which the
      closed-form contact model over-predicts: tan theta_p > (1 + ``base_tolerance``)
      (a - d_n)/a_c (a_c the contact radius). The kernel flags any overshoot (``FLAG_BASE``
      in ``physics_flags``); the default tolerance 0.05 keeps the model error within
      about 2 % in force (1 % in energy). Never reached by the paper's chapter-5 motions
      (closest: 0.92 of the way) and rare under uniform random delta-mode actions (0.5 % of
      the episode ends, one in 20,000 steps); the chapter-4 handling process at grasp
      angles >= 6 deg goes past it (overshoot 4 % at 6 deg, 20 % at 7.2 deg): replay that
      with ``base_tolerance=math.inf``.
    - ``tension``: a fingertip's normal contact impulse over the control step is negative:
      the bilateral contact of the model pulled the object, which a real fingertip cannot.
    - ``slip``: a fingertip's friction ratio over the control step exceeds the hand's
      friction coefficient ``mu`` (below).

    ``tension`` and ``slip`` are checked after the other failures (a step with one of
    those reports it) and end the episode only with
    ``terminate_on_slip=True`` (default); with False they are only reported in ``info``.

    **Friction.** The model enforces rolling without slip and a bilateral normal contact; every
    control step the environment checks that the contact could really hold:
    ``info["friction_ratio"]`` (right and left fingertip) is |J_t| / J_n, the ratio of the
    tangential to the normal contact impulse over the control step (the ratio of the mean
    forces, so that the force spikes of a few 0.1 ms substeps after a set-point jump count with
    their true weight; inf where J_n <= 0). Above the hand's friction coefficient ``mu``
    (default 1.0, soft polyurethane on a dry rigid object; ``hand_overrides={"mu": 0.5}``,
    randomised by ``rand_friction``) the step is a ``slip``. The paper's motions 1-8 need at
    most 0.54.

    Every control step is classified (the residual over all its substeps, the rest at its end;
    the RK4 substeps stop at once on NaN or d_n outside [0, a)). With
    ``terminate_on_success=True``, ``success`` also terminates. ``step`` never raises for
    physics trouble and never returns NaN; ``reset`` starts afresh from the grasp phase,
    whatever the previous episode did. Truncation (``truncated=True``) comes from the
    ``TimeLimit`` wrapper after ``max_episode_steps`` control steps.

    ``info`` of every ``reset`` and ``step``: ``object_pose`` (x, y, theta; m, m, rad),
    ``deformation`` (d_n1, d_n2, d_t1, d_t2; m), ``constraint_error`` (max |C^H| in m, max
    |C^N| in m/s over the step; at reset: at the start state), ``grasped`` (both d_n > 0, state
    valid), ``is_success``, ``setpoint`` (rad), ``physics_flags`` (kernel status bits),
    ``setpoint_latency`` (the episode's set-point latency in control steps, an int drawn at
    reset; 0 without the keyword ``setpoint_latency``), ``friction_ratio`` (shape (2,), see
    Friction), ``contact_impulse`` (J_n1, J_n2, J_t1, J_t2 of the step; N s), ``tension``
    (bool (2,), J_n < 0), the contact keys 0 / False at reset, ``contact_validated`` (bool
    (2,): the fingertip is inside the range where the contact model was validated by the
    paper's compression tests, d_n <= 8 mm and |theta_p| <= 30 deg; outside it, up to the
    hard limits that end the episode (over-compression at a/2, the fingertip base), the model
    extrapolates), the reward terms (0 at reset), ``goal`` (SI, goal tasks) and
    ``termination_reason``: None while the episode runs (at reset, on every step that does
    not terminate, and on a step that is only truncated), else the failure of the list above
    or ``"success"``. The native vector env reports the same values batched
    (``info["termination_reason"]`` an object array with None for the running environments).

    ## Arguments

    Every argument is a ``gym.make(id, **kwargs)`` keyword (the same for
    ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)``).
    ``None`` for a task keyword means the value in ``configs/tasks/<task>.yaml``; a task
    rejects keywords it does not use. Every numeric keyword has a range (column Range;
    ``(`` / ``)`` exclude the end), checked before anything is allocated or run
    (``ValueError`` naming the keyword, the value and its range); the values in the task
    configs are checked the same way. Every reward is finite within them. The table is
    :func:`softhand_env.envs.options.arguments_table`, generated from the fields of
    :class:`~softhand_env.envs.options.EnvOptions`.

{ARGUMENTS_TABLE}

    ## Version History

    - v0: initial release (chapter-5 model, Table 5.1 parameters); ``termination_reason`` in
      every ``info`` (None while the episode runs); ``reward_threshold`` registered for the
      goal tasks (max_episode_steps x goal_weight, see :func:`softhand_env.envs.register_envs`).
    - v0, friction update: ``info["friction_ratio"]``, ``info["contact_impulse"]`` and
      ``info["tension"]`` every step; termination reasons ``"slip"`` and ``"tension"``
      (``terminate_on_slip=True`` by default; False restores the earlier episode ends while
      still reporting); hand parameter ``mu`` (YAML key ``mu``, default 1.0) and
      ``rand_friction`` (preset 0.2 with ``randomize=True``); randomisation ranges checked for
      RK4 stability at construction (``ValueError``). With any ``rand_*`` active, each reset
      draws one more uniform after the goal (the friction coefficient): seeded randomised
      episodes keep their parameters, grasp noise and goal but draw different observation
      noise. Models trained before the update keep loading (the env signature does not
      include episode-end keywords).
    - v0, success update: ``is_success`` is False on a failed step (over-compression, slip,
      tension, ...) even when the object happens to be within tolerance of the goal; before,
      only ``grasped`` was required, so an episode ending in over-compression could count.
    - v0, validity update: ``info["contact_validated"]`` per fingertip.
    - v0, ladder update: ``setpoint_latency`` keyword and the ``Random`` ids (randomisation
      ladder).
    - v0, physical-checks update: keywords ``substep_limits`` (the hard limits tested on every
      RK4 substep) and ``slip_window_ms`` (slip and tension judged on windows of physical
      time); both off by default, which keeps the episodes of v0 bit for bit.
    - v1: every id registered again as ``-v1`` with :data:`softhand_env.envs.V1_KWARGS`; the
      ``-v0`` ids keep the semantics above (``sensor_model="ideal"``, checks off). Physical
      failure checks: ``substep_limits=True`` (over-compression, fingertip base and
      constraint limits on every RK4 substep) and ``slip_window_ms=20`` (slip and tension on
      20 ms windows of physical time, whatever the control period). The ROS2 integrator
      (``hand_overrides={"integrator": "ros2"}``, :data:`softhand_env.envs.V1_HAND_OVERRIDES`)
      in place of RK4 at 0.1 ms. Realistic sensing
      (``sensor_model="realistic"``: quantised, noisy encoders and encoder-differenced
      velocities, motor-current torques with noise and a per-episode offset, noisy tactile
      entries; ``rand_sensors=True`` on the ``Random`` ids), drawn from ``np_random`` after
      the other per-episode draws, so seeded episodes keep their parameters, grasp noise,
      goal and latency. ``sensor_model`` is part of the env signature: a model trained on
      ``-v0`` is refused on ``-v1``.
    - v1, integrator schedule: ROS2 takes 1 ms steps only in the first milliseconds of each
      integration call (after the set-point jump) and steps of up to 2 ms on the rest
      (:func:`softhand_env.physics.rosenbrock.step_schedule`; before, 1 ms throughout):
      within 0.04 mm / 0.08 deg of RK4 at 0.1 ms on the paper's motions (before 0.021 mm /
      0.017 deg); the shipped ``-v1`` agents replayed on their 300 test goals change by at
      most one goal (docs/results.md).
    - v1, set-point ramp: keyword ``setpoint_ramp_ms`` (the set-points move to a step's
      command in 10 ms stairs; an action choice of the agent and a field of the env
      signature); its default 0 keeps the episodes of every id bit for bit.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 50}

    def __init__(
        self,
        task: str = "none",
        action_mode: str = "delta",
        normalize_action: bool = True,
        max_delta_deg: float = 1.0,
        joint_range_deg: tuple[float, float] = (-30.0, 30.0),
        control_dt: float = 0.02,
        obs_mode: str = "proprio",
        history_len: int = 1,
        onset_obs: bool = False,
        grasp_setpoint_deg: tuple[float, float] = (6.0, 6.0),
        grasp_duration: float = 0.5,
        reset_noise_deg: float = 0.0,
        hand: str = "paper_ch5",
        hand_overrides: dict[str, Any] | None = None,
        overcompression_ratio: float = 0.5,
        ch_limit: float = 0.001,
        base_tolerance: float = 0.05,
        terminate_on_slip: bool = True,
        randomize: bool = False,
        rand_width: float | None = None,
        rand_mass: float | None = None,
        rand_inertia: float | None = None,
        rand_stiffness: float | None = None,
        rand_damping: float | None = None,
        rand_gains: float | None = None,
        rand_friction: float | None = None,
        obs_noise: float | None = None,
        setpoint_latency: int = 0,
        sensor_model: str = "ideal",
        rand_sensors: bool = False,
        sensor_noise_scale: float = 1.0,
        goal_x_range_mm: float | None = None,
        goal_theta_range_deg: float | None = None,
        x_tolerance_mm: float | None = None,
        theta_tolerance_deg: float | None = None,
        x_scale_mm: float | None = None,
        theta_scale_deg: float | None = None,
        goal_weight: float | None = None,
        success_weight: float | None = None,
        ctrl_weight: float | None = None,
        failure_weight: float | None = None,
        terminate_on_success: bool | None = None,
        render_mode: str | None = None,
        render_width: int = 480,
        render_height: int = 480,
        substep_limits: bool = False,
        slip_window_ms: float | None = None,
        setpoint_ramp_ms: float = 0.0,
    ):
        #: The keywords of this environment (:class:`~softhand_env.envs.options.EnvOptions`).
        given = locals()
        self.options = EnvOptions(**{name: given[name] for name in KEYWORDS})
        cfg = build_config(self.options)
        self.config = cfg
        self.task = cfg.task
        self.render_mode = render_mode
        self.action_space = cfg.actions.space()
        self.observation_space = cfg.layout.space()
        #: Control period (s).
        self.dt = cfg.dt
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / cfg.dt}
        self._batch = EpisodeBatch(cfg, None)
        #: The hand (a one-hand :class:`~softhand_env.physics.HandPhysics`).
        self.physics = self._batch.physics
        self._renderer: SceneRenderer | None = None
        self._viewer: HumanViewer | None = None

    # ------------------------------------------------------------------------------ reset
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=check_seed(seed))
        goal = reset_goal(options, ("goal",))
        batch = self._batch
        batch.start(0, self.np_random, goal)
        batch.finish_reset(_ONE, (self.np_random,))
        info = batch.info(0)
        if self.render_mode == "human":
            self.render()
        return batch.obs[0].copy(), info

    # ------------------------------------------------------------------------------- step
    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        a = action_array(action, (2,))
        batch = self._batch
        reward, terminated = batch.step_one(a.reshape(1, 2), self.np_random)
        info = batch.info(0)
        if self.render_mode == "human":
            self.render()
        return batch.obs[0].copy(), reward, terminated, False, info

    # ---------------------------------------------------------------------------- helpers
    def observation_from_state(self, state: np.ndarray, setpoint: np.ndarray) -> np.ndarray:
        """The newest observation frame (float32) of the exact read-outs (no sensor model, no
        noise) for a physics state.

        Parameters
        ----------
        state : ndarray, shape (20,)
            Physics state [q, p, z].
        setpoint : ndarray, shape (2,)
            Set-points (rad).
        """
        hand = HandPhysics(self.physics.params, num_hands=1, check_stability=False)
        hand.reset_hand(0, np.asarray(state, dtype=np.float64), setpoint)
        out = np.zeros((1, self.config.layout.frame_size), dtype=np.float32)
        observe_rows(hand.finger_angles, hand.finger_velocities, hand.setpoint,
                     hand.joint_torques, hand.deformation, self.config.layout.tactile, out)
        return out[0]

    @property
    def sensors(self) -> SensorSpec:
        """The sensor model (``sensor_model``; all zeros for ``"ideal"``)."""
        return self.config.sensors

    @property
    def sensor_calibration(self) -> dict[str, np.ndarray]:
        """This episode's torque-sensor calibration: ``torque_bias_nm`` (2,) (N m) and
        ``torque_gain`` (2,) (0 and 1 with ``"ideal"``)."""
        sensing = self._batch.sensing
        if sensing is None:
            return {"torque_bias_nm": np.zeros(2), "torque_gain": np.ones(2)}
        return {"torque_bias_nm": sensing.torque_bias[0].copy(),
                "torque_gain": sensing.torque_gain[0].copy()}

    @property
    def goal(self) -> np.ndarray:
        """Current goal (SI units: m for x, rad for theta), shape (goal_dim,)."""
        return self._batch.goal[0].copy()

    # -------------------------------------------------------------------------- rendering
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without render_mode; pass render_mode='rgb_array' or "
                "'human' to gym.make"
            )
            return None
        if self._renderer is None:
            from softhand_env.envs.rendering import SceneRenderer

            self._renderer = SceneRenderer(self.config.params, *self.config.render_size)
        p = self.physics
        pose = p.object_pose
        goal_pose = self.task.goal_pose(pose, self._batch.goal[0])
        frame = self._renderer.frame(pose, p.finger_angles, p.deformation, p.setpoint,
                                     p.params, goal_pose)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None:
            from softhand_env.envs.rendering import HumanViewer

            self._viewer = HumanViewer(*self.config.render_size, self.metadata["render_fps"])
        self._viewer.show(frame)
        return None

    def close(self) -> None:
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_viewer"] = None  # a window does not pickle; it reopens on the next render
        return state

    def get_keys_to_action(self) -> dict[tuple[str, ...], np.ndarray]:
        """Keyboard map for teleoperation (``gymnasium.utils.play``, ``python -m
        softhand_env.play``): key tuples -> delta actions; see :mod:`softhand_env.envs.keys`."""
        from softhand_env.envs.keys import keys_to_action

        return keys_to_action(self.config.actions.mode)


SoftHandEnv.__doc__ = (SoftHandEnv.__doc__ or "").replace(
    "{ARGUMENTS_TABLE}", arguments_table("markdown", indent=4)
)
