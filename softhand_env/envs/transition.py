"""The transition both environments run: N episodes of one configuration, stepped together.

:class:`EpisodeBatch` holds a :class:`~softhand_env.physics.HandPhysics` of N hands and the
per-episode arrays around it (goals, observations, reward terms, info values). One control step
is :meth:`EpisodeBatch.step`::

    actions -> set-points -> physics.step (kernel, rollback, failure classification)
            -> contact check (slip, tension) -> task.score -> observation -> info values

:class:`~softhand_env.envs.SoftHandEnv` is N = 1 of it (its ``info`` is row 0 of
:meth:`EpisodeBatch.info_values`); :class:`~softhand_env.envs.SoftHandVectorEnv` is N
environments (its batched info masks the same values). Both therefore compute the same
numbers the same way; the vector env agrees bit for bit with N single environments.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from softhand_env.envs.actions import delay_setpoints
from softhand_env.envs.config import EnvConfig
from softhand_env.envs.fused import (
    ENDING_NAMES,
    ENDING_SLIP,
    ENDING_SUCCESS,
    ENDING_TENSION,
    control_step_packed,
    finish_rows,
    finish_step,
    pack_arguments,
    shift_history,
    spread_frame,
    write_starts,
)
from softhand_env.envs.observation import (
    ANGLE_SCALE,
    OBS_BOUND,
    add_frame_noise,
    add_frame_noise_rows,
    observe_rows,
)
from softhand_env.envs.sensors import SensorState
from softhand_env.envs.start import start_episodes
from softhand_env.envs.tasks import GoalTask
from softhand_env.envs.windows import SlipWindows
from softhand_env.physics.hand import (
    READ_SETPOINT,
    READ_SIZE,
    HandPhysics,
    HandReadouts,
    StepStatus,
)
from softhand_env.physics.model import DN_1, DT_1, X_OBJ, initial_finger_angle

#: Action dtypes the compiled one-episode step takes (others go through the batched pieces).
_FUSED_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))
#: The rows of one episode.
_ROW_0 = np.zeros(1, dtype=np.int64)
#: Info keys read from the read-out block: their columns (``take`` copies such a strided
#: column range in a third of the time of ``copy``).
_READ_COLUMNS = {
    "object_pose": np.arange(X_OBJ, X_OBJ + 3),
    "deformation": np.arange(DN_1, DT_1 + 2),
    "setpoint": np.arange(READ_SETPOINT, READ_SETPOINT + 2),
}


def reset_goal(options: Any, allowed: tuple[str, ...]) -> Any:
    """The ``"goal"`` entry of ``reset(options=...)`` (None if absent), after checking that
    ``options`` is None or a dict whose keys are all in ``allowed``.

    Raises ``TypeError`` for non-dict options and ``ValueError`` naming the unknown keys and
    the allowed ones. The goal's shape, finiteness and range are checked by
    :func:`~softhand_env.envs.start.start_episode`.
    """
    if options is None:
        return None
    if not isinstance(options, dict):
        raise TypeError(f"reset options must be a dict or None (got {type(options).__name__})")
    unknown = sorted(str(k) for k in options if k not in allowed)
    if unknown:
        raise ValueError(f"unknown reset options {unknown}; allowed: {sorted(allowed)}")
    return options.get("goal")


def _generator(rngs: Sequence[np.random.Generator | None], i: Any) -> np.random.Generator:
    """Generator of environment ``i`` (seeded by every reset before it is used)."""
    rng = rngs[int(i)]
    if rng is None:
        raise RuntimeError(f"environment {int(i)} has no random generator: call reset first")
    return rng


class EpisodeBatch:
    """N episodes of the environment configured by ``cfg`` (see module doc).

    Parameters
    ----------
    cfg : EnvConfig
    num_envs : int or None
        N >= 1 episodes; None is one episode whose physics has the one-hand shapes
        (``physics.get_state()`` is (20,), see :class:`~softhand_env.physics.HandPhysics`).

    Attributes
    ----------
    physics : HandPhysics
        The N hands.
    goal : ndarray, shape (N, goal_dim)
        Goals (SI units).
    obs : ndarray of float32, shape (N, obs_size)
        Current observations.
    terms : ndarray, shape (n_terms, N)
        Reward terms of the last step (0 after a reset), ordered as ``cfg.task.terms``.
    constraint_error : ndarray, shape (N, 2)
        max |C^H| (m), max |C^N| (m/s) of the last step (at a reset: of the start state).
    flags : ndarray of int64, shape (N,)
        Kernel status flags of the last step (0 after a reset).
    mu : ndarray, shape (N,)
        Friction coefficient of every episode (randomised by ``rand_friction``).
    contact_impulse : ndarray, shape (N, 4)
        Contact impulses (J_n1, J_n2, J_t1, J_t2) of the last step (N s; 0 after a reset).
    friction_ratio : ndarray, shape (N, 2)
        |J_t| / J_n per finger of the last step (inf where J_n <= 0; 0 after a reset).
    tension : ndarray of bool, shape (N, 2)
        Fingers whose normal impulse of the last step was negative (False after a reset).
    grasped, success : ndarray of bool, shape (N,)
    reason : ndarray of object, shape (N,)
        Termination reason of the last step (a failure name, ``"slip"``, ``"tension"`` or
        ``"success"``), else None: a fresh array made from the ending codes kept per episode
        (:data:`~softhand_env.envs.fused.ENDING_NAMES`).
    latency : ndarray of int64, shape (N,)
        Set-point latency of each episode in control steps (``setpoint_latency``; 0 without).
    sensing : SensorState or None
        The sensors of a non-ideal ``sensor_model`` (per-episode calibration, last encoder
        readings; :mod:`softhand_env.envs.sensors`); None with ``"ideal"``, whose
        observation reads the physics' read-outs.

    Set-point latency (``cfg.setpoint_latency`` = K > 0): the set-points commanded at step t
    are applied from step t + L on (L the episode's latency), the ones commanded before stay
    applied meanwhile; an episode starts with the grasp set-points as every earlier command.
    Delta actions and the control cost refer to the commanded set-points; the physics, the
    observation and ``info["setpoint"]`` see the applied ones.
    """

    def __init__(self, cfg: EnvConfig, num_envs: int | None):
        n = 1 if num_envs is None else int(num_envs)
        self.cfg = cfg
        self.task = cfg.task
        self.num_envs = n
        self.physics = HandPhysics(
            cfg.params,
            num_hands=num_envs,
            ch_limit=cfg.ch_limit,
            dn_limit=cfg.dn_limit,
            base_limit=cfg.base_limit,
            # checked once by build_config, with the corners of the randomisation ranges
            check_stability=False,
            substep_limits=cfg.substep_limits,
        )
        #: Slip windows (``slip_window_ms``; None: slip is judged on each control step).
        self.windows = None if cfg.slip_window is None else SlipWindows(n, cfg.slip_window)
        self.goal = np.zeros((n, cfg.task.goal_dim))
        self.obs = np.zeros((n, cfg.layout.size), dtype=np.float32)
        self.terms = np.zeros((len(cfg.task.terms), n))
        self._reward = np.zeros(n)  # the terms' sum of the last step
        self._all_rows = np.arange(n)
        self._failed_one = np.zeros(1, dtype=bool)  # one episode's failure, slip included
        self._failed_any = np.zeros(n, dtype=bool)  # the same of every episode of a batch
        # what a start state is scored with: no control cost, no failure; its terms are
        # dropped
        self._zero = np.zeros(n)
        self._false = np.zeros(n, dtype=bool)
        self._scratch_terms = np.zeros_like(self.terms)
        self._scratch_reward = np.zeros(n)
        self.constraint_error = np.zeros((n, 2))
        self.flags = np.zeros(n, dtype=np.int64)
        self.mu = np.full(n, cfg.params.mu)
        self.radius = np.full(n, cfg.params.a)
        self.validated = np.ones((n, 2), dtype=bool)
        self._no_skip = np.zeros(n, dtype=bool)
        # the outputs of the physics' step and the contact check (overwritten every step)
        self._status = StepStatus.empty(n)
        self._bad = np.empty(n, dtype=bool)
        self.contact_impulse = np.zeros((n, 4))
        self.friction_ratio = np.zeros((n, 2))
        self.tension = np.zeros((n, 2), dtype=bool)
        self.grasped = np.zeros(n, dtype=bool)
        self.success = np.zeros(n, dtype=bool)
        self._ending = np.zeros(n, dtype=np.int64)  # codes of ENDING_NAMES
        self.latency = np.zeros(n, dtype=np.int64)
        # set-points commanded in the last K steps, newest first (only with K > 0)
        self._sent = np.zeros((n, cfg.setpoint_latency, 2))
        self.sensing: SensorState | None = None
        if not cfg.sensors.ideal:
            self.sensing = SensorState(cfg.sensors, n, cfg.dt, cfg.layout.tactile,
                                       cfg.rand_sensors)
        # one episode steps in one compiled call (:mod:`.fused`)
        self._fused = n == 1
        self._applied = np.empty((n, 2))
        self._cmd = np.empty((n, 2))
        self._ctrl = np.empty(n)
        self._failed = np.zeros(n, dtype=bool)
        self._active = np.zeros(n, dtype=bool)
        self._done = np.zeros(n, dtype=np.int64)
        self._substeps = np.zeros(n, dtype=np.int64)
        self._fused_args: tuple[Any, ...] = ()
        # the read-outs of the last step or reset, written in place (``_r`` names the columns)
        self._read_block = np.zeros((n, READ_SIZE))
        self._read_views = HandReadouts.of_block(self._read_block)
        self.physics.read_into(self._read_block)
        self._r = self._read_views
        self._fused_pack: Any = None  # fused.Arguments of _fused_args, built on first use
        self._batch_pack: Any = None  # fused.Arguments of the batched step, the same
        self._rows0 = self._rows(0)  # views, as info reads row 0 every step of a single env
        self._reads0 = self._read_rows0()
        self._info_views()
        self._start_score = self._start_arguments()
        if self._fused:
            self._fused_args = self._fused_arguments(self._failed_one, _ROW_0)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_fused_pack"] = None  # a compiled record does not pickle; rebuilt on use
        state["_batch_pack"] = None
        # views unpickle as copies: these (and the record of arrays for starts) are rebuilt
        # on unpickling
        for views in ("_r", "_read_views", "_rows0", "_reads0", "_info_keys", "_info_copied",
                      "_start_score"):
            del state[views]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._read_views = HandReadouts.of_block(self._read_block)
        self._r = self._read_views
        self._rows0 = self._rows(0)
        self._reads0 = self._read_rows0()
        self._info_views()
        self._start_score = self._start_arguments()

    def _info_views(self) -> None:
        """The key order of :meth:`info_values` and the (key, array) pairs it copies as they
        are (the read-out columns and the reward terms are copied as blocks)."""
        arrays = self._info_arrays()
        self._info_keys = tuple(arrays)
        self._info_copied = tuple((key, value) for key, value in arrays.items()
                                  if key not in _READ_COLUMNS and key not in self.task.terms
                                  and key != "termination_reason")

    @property
    def reason(self) -> np.ndarray:
        """Termination reason of the last step, object (N,) (see the class doc; fresh)."""
        return np.take(ENDING_NAMES, self._ending)

    # ------------------------------------------------------------------------------ reset
    def start(self, i: int, rng: np.random.Generator | None, goal: Any = None) -> None:
        """Start a new episode in environment ``i`` (draws from ``rng``, see
        :func:`~softhand_env.envs.start.start_episode`); call :meth:`finish_reset` next."""
        self.start_rows(np.array([i]), (rng,), None if goal is None else (goal,))

    def start_rows(
        self,
        rows: np.ndarray,
        rngs: Sequence[np.random.Generator | None],
        goals: Sequence[Any] | None = None,
    ) -> None:
        """:meth:`start` of the environments ``rows`` (int (K,)): environment ``rows[k]``
        draws from ``rngs[k]`` (its goal ``goals[k]`` if given), then every array is written
        at once; call :meth:`finish_reset` next."""
        generators = [_generator(rngs, k) for k in range(len(rows))]
        starts = start_episodes(self.cfg, generators, goals)
        self.physics.reset_hands(rows, starts.state, starts.setpoint, starts.params)
        # every earlier command: the grasp set-points
        write_starts(rows, starts.setpoint, starts.latency, starts.goal, starts.mu,
                     starts.radius, self.latency, self._sent, self.goal, self.mu, self.radius,
                     self.terms, self.flags, self.contact_impulse, self.friction_ratio,
                     self.tension, self._ending)
        if self.windows is not None:
            self.windows.restart(rows)
        if self.sensing is not None:  # after every draw of start_episode
            for i, rng in zip(rows.tolist(), generators, strict=True):
                self.sensing.start(i, rng)
        if self.cfg.layout.onset:
            self._write_onset(rows, starts.params, generators)

    def _write_onset(self, rows: np.ndarray, params: Sequence[Any],
                     generators: Sequence[np.random.Generator]) -> None:
        """The grasp-onset entries of the environments ``rows`` (int (K,)) whose episodes
        start with hands ``params`` (K HandParams): the finger angles of the grasp phase's
        first state, the fingertips touching the object undeformed
        (:func:`~softhand_env.physics.model.initial_finger_angle`), read through the sensor
        model (two encoder noises from each environment's generator after its calibration;
        exact with ideal sensors), scaled and clipped like the frames' angles. They stay for
        the episode (no step writes those columns)."""
        angle = np.array([[initial_finger_angle(p)] * 2 for p in params])
        if self.sensing is not None:
            angle = self.sensing.onset(angle, generators)
        h = self.cfg.layout.history_size
        self.obs[rows, h:h + 2] = np.clip(angle / ANGLE_SCALE, -OBS_BOUND, OBS_BOUND)

    def finish_reset(
        self, mask: np.ndarray, rngs: Sequence[np.random.Generator | None]
    ) -> None:
        """Start-state info and observations of the environments of ``mask`` (bool (N,)) just
        started: the first frame in every history slot (noise drawn once from ``rngs[i]``),
        then the goal. The other environments' rows are left as they are."""
        rows = np.flatnonzero(mask)
        layout = self.cfg.layout
        obs = self.obs
        f = layout.frame_size
        noise = self.cfg.randomization.obs_noise
        ideal = self.sensing is None
        # read-outs, start-state success (no action, no failure; the terms stay 0), the goal,
        # and with ideal noise-free sensors the first frame in every history slot
        y, u, prm = self.physics.step_arrays()[:3]
        finish_rows(y, u, prm, rows, self._read_block, self.radius, self.validated,
                    self.constraint_error, self.grasped, ideal, layout.tactile, obs, f,
                    layout.history_len if ideal and noise == 0 else 1, *self._start_score)
        if ideal and noise == 0:
            return
        if not ideal:  # finish_rows wrote the frames of ideal sensors
            obs[rows, :f] = self._frames(rows=rows, rngs=rngs, first=True, subset=True)
        if noise > 0:  # each row from its environment's generator
            add_frame_noise_rows(obs, rows, f, noise, [_generator(rngs, i) for i in rows])
        spread_frame(obs, rows, f, layout.history_len)

    def _frames(
        self,
        out: np.ndarray | None = None,
        rows: Any = (),
        rngs: Sequence[np.random.Generator | None] = (),
        first: bool = False,
        subset: bool = False,
    ) -> np.ndarray:
        """The newest observation frame of every environment, float32 (N, frame_size), written
        into the first frame_size columns of ``out`` if given; with ``subset`` the frames of
        the environments ``rows`` only (K, frame_size).

        With a non-ideal sensor model the environments ``rows`` (array of int) are read
        through it (drawing from ``rngs[i]``; ``first``: the first reading of an episode);
        the other rows' frames are not used by the caller."""
        r = self._r
        angle, velocity, setpoint, torque, deformation = (
            r.finger_angles, r.finger_velocities, r.setpoint, r.joint_torques, r.deformation)
        if self.sensing is not None:
            angle, velocity, torque, deformation = self.sensing.read(
                angle, torque, deformation, rows, [_generator(rngs, i) for i in rows], first)
        if subset:
            angle, velocity, setpoint, torque, deformation = (
                a[rows] for a in (angle, velocity, setpoint, torque, deformation))
        if out is None:
            out = np.empty((angle.shape[0], self.cfg.layout.frame_size), dtype=np.float32)
        observe_rows(angle, velocity, setpoint, torque, deformation, self.cfg.layout.tactile,
                     out)
        return out

    # ------------------------------------------------------------------------------- step
    def step(
        self,
        actions: np.ndarray,
        rngs: Sequence[np.random.Generator | None],
        skip: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One control step of every environment (those of ``skip`` stay untouched).

        Parameters
        ----------
        actions : ndarray, shape (N, 2)
        rngs : sequence of N generators
            Observation noise of environment i comes from ``rngs[i]``.
        skip : ndarray of bool, shape (N,), optional
            Environments that restart instead of stepping (their rows are overwritten by the
            caller's reset; no noise is drawn for them).

        Returns
        -------
        reward : ndarray, shape (N,)
        terminated : ndarray of bool, shape (N,)
        """
        cfg, n = self.cfg, self.num_envs
        # (a single episode steps through step_one and its one compiled call)
        outcome, failed, grasped, contact, ctrl = self._step_physics(actions, skip)
        if self._batch_pack is None:
            self._batch_pack = pack_arguments(
                *self._fused_arguments(self._failed_any, self._all_rows))
        noise = cfg.randomization.obs_noise
        frames = self.sensing is None and noise == 0  # no draws: every row at once
        terminated = np.empty(n, dtype=bool)
        # one compiled call: status, read-outs, score, endings, history and ideal frames
        finish_step(outcome, self._no_skip if skip is None else skip, failed, grasped,
                    contact, ctrl, self._read_block, self.task.terminate_on_success, frames,
                    terminated, self._batch_pack)
        if not frames:
            f = cfg.layout.frame_size
            rows = np.arange(n) if skip is None else np.flatnonzero(~skip)
            self._frames(self.obs, rows=rows, rngs=rngs)
            if noise > 0:
                add_frame_noise_rows(self.obs, rows, f, noise,
                                     [_generator(rngs, i) for i in rows])
        return self._reward.copy(), terminated

    def step_one(self, actions: np.ndarray, rng: np.random.Generator | None) -> tuple[float, bool]:
        """:meth:`step` of one episode (N = 1) on Python scalars: the same numbers as row 0 of
        :meth:`step`, without its array arithmetic (what the single environment runs).

        Parameters
        ----------
        actions : ndarray, shape (1, 2)
        rng : numpy.random.Generator
            The episode's generator (observation noise, sensor readings).

        Returns
        -------
        reward : float
        terminated : bool
        """
        if not (self._fused and isinstance(actions, np.ndarray) and actions.shape == (1, 2)
                and actions.dtype in _FUSED_DTYPES):
            reward, term = self.step(actions, (rng,))
            return float(reward[0]), bool(term[0])
        cfg, task = self.cfg, self.task
        contact_a = self._step_fused(actions)
        contact = cfg.terminate_on_slip and bool(contact_a[0])
        failed = bool(self._failed_one[0])  # slip and tension included when they terminate
        success = bool(self.success[0])  # scored by the compiled step
        terminated = failed or (task.terminate_on_success and success)
        if contact:
            self._ending[0] = ENDING_TENSION if self.tension[0].any() else ENDING_SLIP
        elif terminated and not failed:
            self._ending[0] = ENDING_SUCCESS
        layout = cfg.layout
        f = layout.frame_size
        if self.sensing is not None:  # the fused call wrote the frame of ideal sensors only
            shift_history(self.obs, f, layout.history_size)
            self._frames(self.obs, rows=_ROW_0, rngs=(rng,))
        noise = cfg.randomization.obs_noise
        if noise > 0:
            add_frame_noise(self.obs[0, :f], noise, _generator((rng,), 0))
        return float(self._reward[0]), bool(terminated)

    def _step_physics(
        self, actions: np.ndarray, skip: np.ndarray | None
    ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, Any]:
        """The physics part of :meth:`step`: set-points, then the physics step or the slip
        windows. Returns (outcome, failed, grasped, contact, ctrl): ``outcome`` True for a
        step without slip windows, whose status and contact check
        :func:`~softhand_env.envs.fused.finish_step` records into the bool (N,) arrays
        returned (the windows' accounting wrote them already); ``ctrl`` the control cost
        (N,)."""
        cfg = self.cfg
        if cfg.setpoint_latency:
            u, ctrl = cfg.actions.setpoints(actions, self._sent[:, 0])
            u = self._delay(u)
        else:
            u, ctrl = cfg.actions.setpoints(actions, self._r.setpoint)  # the last commanded
        p, windows = self.physics, self.windows
        if windows is None:
            p.step(u, cfg.n_substeps, strict=False, skip=skip, out=self._status)
            return True, self._failed, self.grasped, self._bad, ctrl
        status = windows.step(p, u, cfg.n_substeps, self.mu, cfg.terminate_on_slip, skip,
                              cfg.setpoint_ramp, cfg.ramp_stair)
        self.contact_impulse[:] = status.impulse
        self.friction_ratio[:] = status.friction_ratio
        self.tension[:] = status.tension
        self.grasped[:] = status.grasped
        self.flags[:] = status.flags
        self.constraint_error[:] = status.constraint_error
        self._ending[:] = status.reason_code
        return False, status.failed, status.grasped, status.contact, ctrl

    def _fused_arguments(self, failed_one: np.ndarray, rows: np.ndarray) -> tuple[Any, ...]:
        """The arguments of :func:`~softhand_env.envs.fused.control_step` after the first
        three (action, previous set-points, read-out block) and the integrator pair: the
        configuration's constants and the arrays updated in place (built once), with
        ``failed_one`` (bool (N,)) the step's failure, slip and tension included when they
        end the episode, and ``rows`` (int (N,)) the rows to score."""
        cfg, p, layout = self.cfg, self.physics, self.cfg.layout
        win = self.windows if self.windows is not None else SlipWindows(1, 1)
        return (
            *cfg.actions.map_constants(),
            self._cmd, self._ctrl, self._sent, self.latency, self._applied,
            *p.step_arrays(), cfg.n_substeps,
            p.ch_limit, p.dn_limit, p.base_limit,
            *self._status.arrays(), self.mu, self._no_skip,
            0 if self.windows is None else win.window, cfg.terminate_on_slip, win.left,
            win.impulse, self._active, self._done, self._substeps, cfg.setpoint_ramp,
            max(cfg.ramp_stair, 1), np.empty((1, 2)), np.empty((1, 2)),
            self.flags, self.constraint_error, self._failed, self.grasped, self._ending,
            self.contact_impulse, self.friction_ratio, self.tension, self._bad,
            self.radius, self.validated, self.sensing is None, layout.tactile, self.obs,
            layout.frame_size, layout.history_size, *self._score_arguments(failed_one, rows),
        )

    def _start_arguments(self) -> tuple[Any, ...]:
        """The scoring and goal arguments of :func:`~softhand_env.envs.fused.finish_rows`
        after ``copies``: a start state is scored with no control cost and no failure, into
        scratch terms and reward."""
        task = self.task
        goal_scale = task._obs_scales if isinstance(task, GoalTask) else np.zeros(0)
        return (*self._task_arguments(), self._zero, self._false, self._scratch_terms,
                self.success, self._scratch_reward, goal_scale, OBS_BOUND)

    def _task_arguments(self) -> tuple[Any, ...]:
        """Whether the task scores, the goals and the task's constants of
        :func:`~softhand_env.envs.tasks.score_rows` (empty without a goal)."""
        task = self.task
        if isinstance(task, GoalTask):
            constants = (task._index, task._tolerance, task._scale, task._weights)
        else:
            constants = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(4))
        return (isinstance(task, GoalTask), self.goal, *constants)

    def _score_arguments(self, failed_one: np.ndarray, rows: np.ndarray) -> tuple[Any, ...]:
        """The scoring arguments of :func:`~softhand_env.envs.fused.control_step`: whether
        the task scores, its goal and constants (empty without a goal), the outputs
        (``failed_one`` the step's failure and ``rows`` the rows scored, see
        :meth:`_fused_arguments`)."""
        return (*self._task_arguments(), failed_one, self.terms, self.success, self._reward,
                rows)

    def _step_fused(self, actions: np.ndarray) -> np.ndarray:
        """The physics and the rest of :meth:`step` of one episode in one compiled call
        (:func:`~softhand_env.envs.fused.control_step`; with ideal sensors also the newest
        observation frame; the task's score). Returns the contact flags (1,) (slip or
        tension)."""
        p = self.physics
        if self._fused_pack is None:
            self._fused_pack = pack_arguments(*self._fused_args)
        # the previous commanded set-points (with latency not those applied), read before the
        # call writes the read-outs into the block kept for the episode (info copies its rows)
        prev = self._sent[:, 0] if self.cfg.setpoint_latency else self._r.setpoint
        ok = control_step_packed(actions, prev, self._read_block,
                                 p.integrator == "ros2", p.ros2_dt, self._fused_pack)
        if not ok:
            raise ValueError(f"action must be finite (got {actions.tolist()})")
        return self._bad

    def _delay(self, u: np.ndarray) -> np.ndarray:
        """Record the commanded set-points ``u`` (N, 2); return those to apply this step: the
        ones commanded ``latency`` steps ago (see the class doc; overwritten by the next
        step)."""
        delay_setpoints(u, self._sent, self.latency, self._applied)
        return self._applied

    # ------------------------------------------------------------------------------- info
    def info_values(self) -> dict[str, np.ndarray]:
        """Per-environment info values (row i is environment i's ``info``), in key order.

        ``object_pose`` (N, 3) (x, y, theta; m, m, rad), ``deformation`` (N, 4) (d_n1, d_n2,
        d_t1, d_t2; m), ``constraint_error`` (N, 2) (max |C^H| in m, max |C^N| in m/s over the
        step), ``grasped`` (N,), ``is_success`` (N,), ``setpoint`` (N, 2) (rad),
        ``physics_flags`` (N,) (kernel status bits), ``setpoint_latency`` (N,) (int64: each
        episode's set-point latency in control steps), ``friction_ratio`` (N, 2) (|J_t| / J_n
        per finger over the step; inf where J_n <= 0; with ``slip_window_ms``: the largest
        over the windows that ended in the step, 0 if none did, see
        :mod:`softhand_env.envs.windows`), ``contact_impulse`` (N, 4) (J_n1, J_n2, J_t1, J_t2
        over the step; N s), ``tension`` (N, 2) (bool: J_n < 0 over the step, or in a window
        that ended in it), ``contact_validated`` (N, 2)
        (bool: fingertip inside the contact model's validated box), ``termination_reason`` (N,)
        (None while the episode runs), ``goal`` (N, goal_dim) for goal tasks, then the reward
        terms (N,). The three contact keys are 0 / False at a reset (no step taken). Fresh
        arrays.
        """
        block = self._read_block
        values = {key: value.copy() for key, value in self._info_copied}
        values["termination_reason"] = self.reason
        for key, columns in _READ_COLUMNS.items():
            values[key] = block.take(columns, axis=1)
        terms = self.terms.copy()  # one fresh block, one row per term
        for k, name in enumerate(self.task.terms):
            values[name] = terms[k]
        return {key: values[key] for key in self._info_keys}

    def info(self, i: int = 0) -> dict[str, Any]:
        """``info`` of environment ``i`` as a single environment returns it: the row i of
        :meth:`info_values`, with Python scalars for the scalar keys."""
        # the keys of _info_arrays, built directly (a single env does this every step)
        r = self._r
        ce, fr, ci, te, va, go = (self._rows0 if i == 0 else self._rows(i))
        if i == 0:
            pose, deformation, setpoint = self._reads0
        else:
            pose, deformation, setpoint = r.object_pose[i], r.deformation[i], r.setpoint[i]
        info: dict[str, Any] = {
            "object_pose": pose.copy(),
            "deformation": deformation.copy(),
            "constraint_error": ce.copy(),
            "grasped": bool(self.grasped[i]),
            "is_success": bool(self.success[i]),
            "setpoint": setpoint.copy(),
            "physics_flags": int(self.flags[i]),
            "setpoint_latency": int(self.latency[i]),
            "friction_ratio": fr.copy(),
            "contact_impulse": ci.copy(),
            "tension": te.copy(),
            "contact_validated": va.copy(),
            "termination_reason": ENDING_NAMES[self._ending[i]],
        }
        if self.task.goal_dim:
            info["goal"] = go.copy()
        info.update(zip(self.task.terms, self.terms[:, i].tolist(), strict=True))
        return info

    def _rows(self, i: int) -> tuple[np.ndarray, ...]:
        """Row ``i`` of the per-step info arrays that :meth:`info` copies (views)."""
        return (self.constraint_error[i], self.friction_ratio[i], self.contact_impulse[i],
                self.tension[i], self.validated[i], self.goal[i])

    def _read_rows0(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Row 0 of the read-out block's object pose, deformation and set-points (views, what
        :meth:`info` copies while the read-outs are that block's)."""
        v = self._read_views
        return v.object_pose[0], v.deformation[0], v.setpoint[0]

    def _info_arrays(self) -> dict[str, np.ndarray]:
        """The arrays behind :meth:`info_values` (not copied: callers copy)."""
        r = self._r
        values: dict[str, np.ndarray] = {
            "object_pose": r.object_pose,
            "deformation": r.deformation,
            "constraint_error": self.constraint_error,
            "grasped": self.grasped,
            "is_success": self.success,
            "setpoint": r.setpoint,
            "physics_flags": self.flags,
            "setpoint_latency": self.latency,
            "friction_ratio": self.friction_ratio,
            "contact_impulse": self.contact_impulse,
            "tension": self.tension,
            "contact_validated": self.validated,
            "termination_reason": self._ending,  # codes: info_values names them
        }
        if self.task.goal_dim:
            values["goal"] = self.goal
        for k, name in enumerate(self.task.terms):
            values[name] = self.terms[k]
        return values
