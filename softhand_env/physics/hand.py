"""Physics of the soft hand: owns the states of N hands, advances them, classifies failures.

:class:`HandPhysics` is the dm_control-style Physics object both environments use: it holds
the 20-element states of :mod:`softhand_env.physics.model` of N >= 1 hands with their packed
parameters and set-points, advances them together with the lane-batched kernel
(:func:`softhand_env.physics.kernel.advance_batch`) under constant finger-angle set-points, rolls a
hand whose state became non-finite back to its state before the step, classifies every hand's
failure (:func:`softhand_env.physics.failure.classify`) and reports it in a :class:`StepStatus`
(``strict=True`` raises :class:`PhysicsError` on divergence instead). Environment code reads
the hands through the named read-outs (``object_pose``, ``finger_angles``, ...), never through
state indices. Every read-out returns a copy.

Shapes: ``HandPhysics(params)`` is one hand and its read-outs have no hand axis (``object_pose``
is (3,)); ``HandPhysics(params, num_hands=N)`` (N >= 1, the environments' form) gives every
read-out and status field a leading hand axis (``object_pose`` is (N, 3)).
"""

from __future__ import annotations

import math
import time
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from softhand_env.physics import (
    friction,
    jit_cache,  # noqa: F401  (the package stamp on cached kernels)
    kernel,
    rosenbrock,
)
from softhand_env.physics.dispatch import ParallelChoice
from softhand_env.physics.failure import REASONS, classify
from softhand_env.physics.model import (
    DN_1,
    DT_1,
    N_DIAG,
    NQ,
    NY,
    P_KD,
    P_KI,
    P_KP,
    TH_1,
    X_OBJ,
    constraint_residuals,
    csm_rhs,
    initial_state,
    pack_params,
    pid_torque,
    pid_torques_batch,
    with_stop_limits,
)
from softhand_env.physics.params import HandParams

# the a-priori RK4 stability check lives in softhand_env.physics.stability; these names stay
# importable from here
from softhand_env.physics.stability import (  # noqa: F401
    RK4_REAL_STABILITY,
    check_rk4_stability,
    rk4_stability_margins,
    warn_if_unstable,
)


class PhysicsError(RuntimeError):
    """The simulated state left the model's validity (NaN or constraint blow-up)."""

    def __init__(self, message: str, flags: int):
        super().__init__(message)
        self.flags = flags


FLAG_NAMES = {
    kernel.FLAG_NONFINITE: "nonfinite_state",
    kernel.FLAG_CONSTRAINT: "constraint_violation",
    kernel.FLAG_LOST: "grasp_lost",
    kernel.FLAG_OVERCOMPRESSED: "overcompressed",
    kernel.FLAG_BASE: "contact_past_base",
}


def describe_flags(flags: int) -> list[str]:
    """Names of the status flags set in ``flags`` (see :mod:`softhand_env.physics.kernel`)."""
    return [name for bit, name in FLAG_NAMES.items() if flags & bit]


#: Failure code (the ``reason`` array of a compiled step) -> name, None for 0 (no failure).
REASON_NAMES = np.array((None, *REASONS), dtype=object)


class StepStatus:
    """Outcome of :meth:`HandPhysics.step`, per hand.

    Every attribute has the physics' hand shape: a scalar for a one-hand
    ``HandPhysics(params)``, an array with a leading axis of N hands for
    ``HandPhysics(params, num_hands=N)``. Further per-step diagnostics are added as further
    attributes of the same shape.

    Attributes
    ----------
    flags : int or ndarray of int64
        Bitwise OR of the kernel status flags (0 = valid); ``FLAG_CONSTRAINT`` wherever the
        step's max |C^H| exceeded ``ch_limit``.
    substeps : int or ndarray of int64
        RK4 substeps taken (fewer than requested only if a fatal flag stopped integration).
    max_ch : float or ndarray
        Largest |C^H| (m) over the visited states (+inf if non-finite in a failed hand).
    max_cn : float or ndarray
        Largest |C^N| (m/s) over the visited states (+inf if non-finite in a failed hand).
    constraint_error : ndarray, shape (2,) or (N, 2)
        (max_ch, max_cn) together (a view of the step's diagnostics).
    failed : bool or ndarray of bool
        A physical failure (see :mod:`softhand_env.physics.failure`): the episode must end.
    grasped : bool or ndarray of bool
        Both d_n > 0 and the state did not diverge.
    reason : str, None or ndarray of object
        Name of the failure reported (:data:`~softhand_env.physics.failure.REASONS`), None if none.
    impulse : ndarray, shape (4,) or (N, 4)
        Contact impulses over the substeps taken (N s): normal J_n1, J_n2 (integral of the
        holonomic multipliers; > 0 pushes the fingertip into the object), tangential J_t1,
        J_t2 (integral of the rolling multipliers), see :mod:`softhand_env.physics.friction`.
        Zero for a hand skipped this step.
    friction_ratio : ndarray, shape (2,) or (N, 2)
        |J_t| / J_n per finger over the step (dimensionless; inf where J_n <= 0).
    tension : ndarray of bool, shape (2,) or (N, 2)
        True per finger whose normal impulse over the step is negative (the contact pulled).
    """

    __slots__ = ("_flags", "_diag", "_failed", "_grasped", "_reason", "_batched")

    def __init__(self, flags: np.ndarray, diag: np.ndarray, failed: np.ndarray,
                 grasped: np.ndarray, reason: np.ndarray, batched: bool = True):
        self._flags = flags
        self._diag = diag
        self._failed = failed
        self._grasped = grasped
        self._reason = reason
        self._batched = batched

    @classmethod
    def empty(cls, num_hands: int) -> StepStatus:
        """A status of ``num_hands`` hands with the hand axis and uninitialised arrays (the
        ``out`` of :meth:`HandPhysics.step`)."""
        n = int(num_hands)
        return cls(np.empty(n, dtype=np.int64), np.empty((n, kernel.N_STEP_DIAG)),
                   np.empty(n, dtype=bool), np.empty(n, dtype=bool),
                   np.empty(n, dtype=np.int64))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The buffers a compiled step writes (hand axis): flags (N,), diagnostics
        (N, ``kernel.N_STEP_DIAG``), failed (N,), grasped (N,), failure code (N,)."""
        return self._flags, self._diag, self._failed, self._grasped, self._reason

    def _hand(self, a: np.ndarray) -> Any:
        return a if self._batched else a[0].item()

    @property
    def hands(self) -> StepStatus:
        """This status with the hand axis (N, ...) on every attribute, also for one hand."""
        if self._batched:
            return self
        return StepStatus(self._flags, self._diag, self._failed, self._grasped, self._reason)

    @property
    def flags(self) -> Any:
        return self._hand(self._flags)

    @property
    def substeps(self) -> Any:
        return self._hand(self._diag[:, 2].astype(np.int64))

    @property
    def impulse(self) -> np.ndarray:
        imp = self._diag[:, kernel.IMPULSE_OFFSET : kernel.IMPULSE_OFFSET + 4].copy()
        return imp if self._batched else imp[0]

    @property
    def friction_ratio(self) -> np.ndarray:
        return friction.friction_ratio(self.impulse)

    @property
    def tension(self) -> np.ndarray:
        return friction.tension(self.impulse)

    @property
    def constraint_error(self) -> np.ndarray:
        return self._diag[:, :2] if self._batched else self._diag[0, :2]

    @property
    def max_ch(self) -> Any:
        return self._hand(self._diag[:, 0])

    @property
    def max_cn(self) -> Any:
        return self._hand(self._diag[:, 1])

    @property
    def failed(self) -> Any:
        return self._hand(self._failed)

    @property
    def grasped(self) -> Any:
        return self._hand(self._grasped)

    @property
    def reason(self) -> Any:
        names = REASON_NAMES[self._reason]
        return names if self._batched else names[0]

    @property
    def fatal(self) -> Any:
        """True where the state left the model (NaN, blow-up, lost grasp, over-compression)."""
        return self._hand((self._flags & kernel.FATAL_FLAGS) != 0)

    @property
    def reasons(self) -> list[str]:
        """Names of the kernel flags set (in any hand)."""
        return describe_flags(int(np.bitwise_or.reduce(self._flags)))

    def __repr__(self) -> str:
        return (
            f"StepStatus(flags={self.flags!r}, substeps={self.substeps!r}, "
            f"max_ch={self.max_ch!r}, max_cn={self.max_cn!r}, failed={self.failed!r}, "
            f"grasped={self.grasped!r}, reason={self.reason!r})"
        )


@njit(cache=True)
def _set_setpoints(SRC, U):
    """Copy the set-points SRC (N, 2) (rad) into U if every entry is finite; False (U
    untouched) otherwise."""
    for s in range(SRC.shape[0]):
        for j in range(2):
            if not math.isfinite(SRC[s, j]):
                return False
    U[:] = SRC
    return True


@njit(cache=True)
def _prepare_step(SRC, U, Y, Y_PREV, FLAGS, DIAG, SKIP):
    """Before a batched kernel call, in one compiled call: :func:`_set_setpoints` from SRC
    (returns False, with nothing changed, if SRC is not finite), the states Y into Y_PREV
    (the rollback), FLAGS 0 (``FLAG_SKIP`` for the hands of SKIP, bool (N,)), DIAG 0."""
    if not _set_setpoints(SRC, U):
        return False
    Y_PREV[:] = Y
    for s in range(FLAGS.shape[0]):
        FLAGS[s] = kernel.FLAG_SKIP if SKIP[s] else 0
    DIAG[:] = 0.0
    return True


@njit(cache=True)
def _step_batch(SRC, Y, U, PRM, TIME, Y_PREV, SKIP, n, ros2, H, ch_limit, dn_limit, base_limit,
                FLAGS, DIAG, FAILED, GRASPED, REASON):
    """A step of N hands on the calling thread in one compiled call (what
    :meth:`HandPhysics.step` does): :func:`_prepare_step` from SRC (N, 2) (rad) with the
    rollback states into Y_PREV and the hands of SKIP (bool (N,)) skipped, then the kernel
    (:mod:`.kernel`'s RK4, or with ``ros2`` :mod:`softhand_env.physics.rosenbrock` at step
    ``H`` (s)), then :func:`_finish_step`, into the outputs FLAGS, DIAG, FAILED, GRASPED,
    REASON (the shapes of :class:`StepStatus`). Every hand must have the same integrator and,
    under ROS2, the same ``dt`` (:meth:`HandPhysics.set_params` keeps them so). Returns False,
    with nothing changed, if SRC is not finite.

    The kernels' parallel versions are called from Python (:meth:`HandPhysics.step`), never
    from a cached compiled function: numba's cached code of a caller compiled in a process
    that loaded its ``parallel=True`` callee from the cache names that callee's threaded
    kernel as that process numbered it, and crashes the next process that loads it."""
    if not _prepare_step(SRC, U, Y, Y_PREV, FLAGS, DIAG, SKIP):
        return False
    if ros2:
        rosenbrock.advance_batch_serial(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS)
    else:
        kernel.advance_batch_serial(Y, U, PRM, n, ch_limit, DIAG, FLAGS)
    _finish_step(FLAGS, Y, Y_PREV, PRM, DIAG, TIME, ch_limit, dn_limit, base_limit, FAILED,
                 GRASPED, REASON)
    return True


@njit(cache=True)
def _step_on_this_thread(SRC, Y, U, PRM, TIME, n, ros2, H, ch_limit, dn_limit, base_limit,
                         FLAGS, DIAG, FAILED, GRASPED, REASON):
    """One step of hands none of which is skipped, on the calling thread, in one compiled call
    (what :meth:`HandPhysics.step` does for one hand): :func:`_step_batch` without a skipped
    hand, serial. Returns False, with nothing changed, if SRC is not finite."""
    return _step_batch(SRC, Y, U, PRM, TIME, np.empty_like(Y),
                       np.zeros(Y.shape[0], dtype=np.bool_), n, ros2, H, ch_limit,
                       dn_limit, base_limit, FLAGS, DIAG, FAILED, GRASPED, REASON)


@njit(cache=True)
def _finish_step(FLAGS, Y, Y_PREV, PRM, DIAG, TIME, ch_limit, dn_limit, base_limit, FAILED,
                 GRASPED, REASON):
    """After the kernel: classify the hands (:func:`softhand_env.physics.failure.classify`, with the
    rollback of non-finite states to ``Y_PREV``) into FAILED, GRASPED, REASON (N,) and advance
    TIME (N,) (s) by the substeps taken (``DIAG[:, 2]``), in one compiled call."""
    classify(FLAGS, Y, Y_PREV, PRM, DIAG, ch_limit, dn_limit, base_limit, FAILED, GRASPED,
             REASON)
    for s in range(Y.shape[0]):
        TIME[s] += DIAG[s, 2] * PRM[s, kernel.P_DT]


@njit(cache=True)
def _constraint_errors(Y, PRM, ROWS, OUT):
    """max |C^H| (m) and max |C^N| (m/s) over the two fingers of the states Y[ROWS[k]] (Y
    (N, 20), parameters PRM (N, N_PARAMS)) into OUT[k] (OUT (K, 2))."""
    res = np.empty(4)
    for k in range(ROWS.shape[0]):
        i = ROWS[k]
        constraint_residuals(Y[i], PRM[i], res)
        OUT[k, 0] = max(abs(res[0]), abs(res[1]))
        OUT[k, 1] = max(abs(res[2]), abs(res[3]))


class HandReadouts(NamedTuple):
    """The named read-outs of every hand at one instant (fresh arrays, leading hand axis N).

    Attributes
    ----------
    object_pose : ndarray, shape (N, 3)
        Object (x, y, theta) in m, m, rad.
    object_velocity : ndarray, shape (N, 3)
        Object (dx/dt, dy/dt, dtheta/dt) in m/s, m/s, rad/s.
    finger_angles : ndarray, shape (N, 2)
        Joint angles (theta_1, theta_2) in rad.
    finger_velocities : ndarray, shape (N, 2)
        Joint velocities in rad/s.
    deformation : ndarray, shape (N, 4)
        Fingertip deformations (d_n1, d_n2, d_t1, d_t2) in m.
    setpoint : ndarray, shape (N, 2)
        Finger-angle set-points (rad).
    joint_torques : ndarray, shape (N, 2)
        PID joint torques (N m) of Eq 5.42.
    """

    object_pose: np.ndarray
    object_velocity: np.ndarray
    finger_angles: np.ndarray
    finger_velocities: np.ndarray
    deformation: np.ndarray
    setpoint: np.ndarray
    joint_torques: np.ndarray

    @classmethod
    def of_block(cls, read: np.ndarray) -> HandReadouts:
        """The read-outs as views of a block (N, :data:`READ_SIZE`) filled by
        :func:`fill_readouts`."""
        return cls(
            read[:, X_OBJ : X_OBJ + 3],
            read[:, NQ + X_OBJ : NQ + X_OBJ + 3],
            read[:, TH_1 : TH_1 + 2],
            read[:, NQ + TH_1 : NQ + TH_1 + 2],
            read[:, DN_1 : DT_1 + 2],
            read[:, READ_SETPOINT : READ_SETPOINT + 2],
            read[:, READ_TORQUE : READ_TORQUE + 2],
        )


#: Columns of a read-out block (N, READ_SIZE) (:func:`fill_readouts`): the state [0, NY),
#: the set-points [READ_SETPOINT, READ_SETPOINT + 2) (rad), the PID torques
#: [READ_TORQUE, READ_TORQUE + 2) (N m).
READ_SETPOINT = NY
READ_TORQUE = NY + 2
READ_SIZE = NY + 4


@njit(cache=True)
def fill_readouts(Y, U, PRM, READ):
    """The read-outs of the states Y (N, 20) under the set-points U (N, 2) (parameters PRM)
    into the block READ (N, :data:`READ_SIZE`) (:meth:`HandReadouts.of_block`)."""
    for s in range(Y.shape[0]):
        _fill_readout_row(Y, U, PRM, READ, s)


@njit(cache=True, inline="always")
def _fill_readout_row(Y, U, PRM, READ, s):
    """The read-outs of hand ``s`` into row ``s`` of READ (:func:`fill_readouts`); element by
    element (row slices cost more than the copy of 24 numbers)."""
    for j in range(NY):
        READ[s, j] = Y[s, j]
    for i in range(2):
        READ[s, READ_SETPOINT + i] = U[s, i]
        READ[s, READ_TORQUE + i] = pid_torque(
            Y[s, TH_1 + i], U[s, i], Y[s, NQ + TH_1 + i], Y[s, 2 * NQ + i],
            PRM[s, P_KP], PRM[s, P_KD], PRM[s, P_KI])


@njit(cache=True)
def fill_readout_rows(Y, U, PRM, ROWS, READ):
    """:func:`fill_readouts` of the hands ROWS (int (K,)) only; the other rows of READ are
    left as they are."""
    for k in range(ROWS.shape[0]):
        _fill_readout_row(Y, U, PRM, READ, ROWS[k])


class HandPhysics:
    """States, integration, failure classification and read-outs of N hands (chapter-5 model).

    The integrator (``params.integrator``: ``"rk4"`` at ``dt`` or ``"ros2"`` at ``ros2_dt``,
    :mod:`softhand_env.physics.rosenbrock`) is one for all hands; under ``"ros2"`` all hands
    also share ``dt`` and ``ros2_dt`` (:meth:`set_params` refuses others).

    Parameters
    ----------
    params : HandParams, optional
        Physical and numerical parameters (SI) of every hand (default: Table 5.1).
    num_hands : int, optional
        N >= 1 hands with a leading hand axis on every read-out; None (default) is one hand
        without that axis (see the module doc).
    ch_limit : float
        |C^H| (m) above which a state counts as diverged (default 1e-3 m).
    dn_limit : float, optional
        d_n (m) at or above which a fingertip counts as over-compressed (default: the
        fingertip radius a, where the model ends).
    base_limit : float
        Allowed reach of a contact circle past its fingertip base before it counts as a
        failure (1 = none; ``math.inf`` = never), see :func:`.contact.beyond_base`.
    check_stability : bool
        Warn (``RuntimeWarning``) if the step is beyond the stability limit of the
        integrator ``params.integrator`` (:func:`warn_if_unstable`); also on
        :meth:`set_params`.
    substep_limits : bool
        Test ``dn_limit``, ``base_limit`` and ``ch_limit`` on every RK4 substep in the
        kernel and end a step at the first substep beyond one of them (the kernel's stop
        limits, :func:`.model.with_stop_limits`); False (default): the kernel stops only at
        d_n >= a and the three limits are judged on the state at the end of the step (and
        the step's largest |C^H|).
    """

    def __init__(
        self,
        params: HandParams | None = None,
        num_hands: int | None = None,
        ch_limit: float = kernel.CH_LIMIT,
        dn_limit: float | None = None,
        base_limit: float = 1.0,
        check_stability: bool = True,
        substep_limits: bool = False,
    ):
        if num_hands is not None and (
            isinstance(num_hands, bool)
            or not isinstance(num_hands, (int, np.integer))
            or num_hands < 1
        ):
            raise ValueError(f"num_hands must be None or an int >= 1 (got {num_hands!r})")
        params = params if params is not None else HandParams()
        if check_stability:
            warn_if_unstable(params, stacklevel=2)
        n = 1 if num_hands is None else int(num_hands)
        self._batched = num_hands is not None
        self._n = n
        self.ch_limit = float(ch_limit)
        self.dn_limit = float(params.a if dn_limit is None else dn_limit)
        self.base_limit = float(base_limit)
        self.substep_limits = bool(substep_limits)
        self._params: list[HandParams] = [params] * n
        self._integrator = params.integrator
        self._ros2_dt = params.ros2_dt
        self._prm = np.ascontiguousarray(np.tile(self._pack(params), (n, 1)))
        self._y = np.tile(initial_state(params), (n, 1))
        self._u = self._y[:, TH_1 : TH_1 + 2].copy()
        self._time = np.zeros(n)
        self._y_prev = np.empty_like(self._y)  # the states before a batched step (rollback)
        self._no_skip = np.zeros(n, dtype=bool)
        self._check_stability = bool(check_stability)
        # serial or parallel batched calls, by measured time (results the same either way),
        # for at least two blocks of lanes under ROS2 (one block does not share), 2 hands RK4;
        # None: always on the calling thread
        parallel_min = 2 * kernel.LANES if self._integrator == "ros2" else 2
        self._dispatch = ParallelChoice() if n >= parallel_min else None

    # ----------------------------------------------------------------- state management
    @property
    def num_hands(self) -> int:
        """Number of hands N (1 for a one-hand physics)."""
        return self._n

    def _out(self, a: np.ndarray) -> Any:
        """Copy of a per-hand array in the physics' hand shape (module doc)."""
        return a.copy() if self._batched else a[0].copy()

    def _hand_array(self, name: str, value: Any, tail: tuple[int, ...]) -> np.ndarray:
        """``value`` as a float64 (N, *tail) array; ValueError naming ``name`` otherwise.

        Accepts the hand shape (``tail`` for one hand, (N, *tail) for N) and (N, *tail)."""
        a = np.asarray(value, dtype=np.float64)
        shape = (self._n, *tail)
        if a.shape != shape and not (not self._batched and a.shape == tail):
            hand = shape if self._batched else tail
            raise ValueError(f"{name} must have shape {hand} (got {np.shape(value)})")
        total = float(a.sum())  # finite sum: every entry finite (the exact test otherwise)
        if total - total != 0.0 and not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (got {a.tolist()})")
        return a.reshape((self._n, *tail))

    @property
    def integrator(self) -> str:
        """Name of the integrator of every hand (``"rk4"`` or ``"ros2"``)."""
        return self._integrator

    @property
    def ros2_dt(self) -> float:
        """Step of the ROS2 integrator (s), used when :attr:`integrator` is ``"ros2"``."""
        return self._ros2_dt

    @property
    def dt(self) -> float:
        """RK4 substep (s) of the first hand."""
        return self._params[0].dt

    @property
    def params(self) -> Any:
        """Parameters: a HandParams (one hand) or a tuple of N (one per hand)."""
        return tuple(self._params) if self._batched else self._params[0]

    @property
    def time(self) -> Any:
        """Simulated time since each hand's last reset (s)."""
        return self._out(self._time) if self._batched else float(self._time[0])

    @property
    def packed_params(self) -> np.ndarray:
        """Copy of the packed parameter vectors, shape (N_PARAMS,) or (N, N_PARAMS)."""
        return self._out(self._prm)

    def reset(self, state: np.ndarray | None = None) -> None:
        """Reset every hand to ``state`` ((20,) or (N, 20)) or to the paper's initial state.

        The set-points become the finger angles (nothing commanded yet).
        """
        if state is None:
            for i, p in enumerate(self._params):
                self._y[i] = initial_state(p)
        else:
            self.set_state(state)
        self._u[:] = self._y[:, TH_1 : TH_1 + 2]
        self._time[:] = 0.0

    def reset_hand(
        self,
        index: int,
        state: np.ndarray,
        setpoint: np.ndarray,
        params: HandParams | None = None,
    ) -> None:
        """Start hand ``index`` afresh at ``state`` (20,) with set-points ``setpoint`` (2,) (rad);
        ``params`` (optional) replace its parameters (packed here)."""
        self.reset_hands(np.array([index]), np.asarray(state)[None], np.asarray(setpoint)[None],
                         [self._params[index] if params is None else params])

    def reset_hands(
        self,
        rows: np.ndarray,
        states: np.ndarray,
        setpoints: np.ndarray,
        params: list[HandParams],
    ) -> None:
        """:meth:`reset_hand` of the hands ``rows`` (int (K,)) at once: states (K, 20),
        set-points (K, 2) (rad), one :class:`HandParams` per hand (packed where they differ
        from the hand's present ones)."""
        for i, prm in zip(rows.tolist(), params, strict=True):
            if prm is not self._params[i]:
                self.set_params(prm, i)
        self._y[rows] = states
        self._u[rows] = setpoints
        self._time[rows] = 0.0

    def set_params(self, params: HandParams, index: int | None = None) -> None:
        """Change the parameters of hand ``index`` (all hands if None); states are kept."""
        if self._check_stability:
            warn_if_unstable(params, stacklevel=2)
        rows = range(self._n) if index is None else (index,)
        if index is not None and self._n > 1:
            first = self._params[1 if index == 0 else 0]
            same = params.integrator == first.integrator and (
                params.integrator == "rk4"
                or (params.dt == first.dt and params.ros2_dt == first.ros2_dt)
            )
            if not same:
                raise ValueError(
                    "every hand of a HandPhysics must use the same integrator (and, under "
                    f"'ros2', the same dt and ros2_dt): got integrator={params.integrator!r}, "
                    f"dt={params.dt!r}, ros2_dt={params.ros2_dt!r} for hand {index}, "
                    f"the others have {first.integrator!r}, {first.dt!r}, {first.ros2_dt!r}"
                )
        else:
            self._integrator = params.integrator
            self._ros2_dt = params.ros2_dt
        prm = self._pack(params)
        for i in rows:
            self._params[i] = params
            self._prm[i] = prm

    def _pack(self, params: HandParams) -> np.ndarray:
        """Packed parameters of a hand with this physics' stop limits (``substep_limits``)."""
        prm = pack_params(params)
        if self.substep_limits:
            with_stop_limits(prm, self.dn_limit, self.base_limit, self.ch_limit)
        return prm

    def get_state(self) -> np.ndarray:
        """Copy of the states [q (9), p (9), z (2)], shape (20,) or (N, 20)."""
        return self._out(self._y)

    def set_state(self, state: np.ndarray) -> None:
        """Set the full states ((20,) or (N, 20)); ValueError on wrong shape or non-finite."""
        self._y[:] = self._hand_array("state", state, (NY,))

    @property
    def setpoint(self) -> np.ndarray:
        """Finger-angle set-points (rad) of the last step, shape (2,) or (N, 2)."""
        return self._out(self._u)

    # ------------------------------------------------------------------------- stepping
    def step(
        self,
        setpoint: np.ndarray,
        n_substeps: int,
        strict: bool = True,
        skip: np.ndarray | None = None,
        out: StepStatus | None = None,
    ) -> StepStatus:
        """Advance every hand ``n_substeps`` substeps of ``dt`` holding the set-points
        ``setpoint`` (RK4 substeps, or that time in ROS2 steps under ``integrator="ros2"``).

        A hand whose state became non-finite is rolled back to its state before the step;
        every hand is then classified (:func:`softhand_env.physics.failure.classify`).

        Parameters
        ----------
        setpoint : array_like, shape (2,) or (N, 2)
            Desired finger angles (theta_1^d, theta_2^d) in rad (one hand: (2,) or (1, 2)).
        n_substeps : int
            Number of substeps of :attr:`dt` seconds.
        strict : bool
            If True, raise :class:`PhysicsError` when a state diverges (NaN or
            |C^H| > ch_limit); lost grasp and over-compression are reported in the status.
        skip : ndarray of bool, shape (N,), optional
            Hands left untouched this step (e.g. environments that restart instead); their
            status reads flags 0, not failed, not grasped.
        out : StepStatus, optional
            A status with the hand axis (:meth:`StepStatus.empty` of N hands) whose arrays
            receive this step's status (overwritten by every step it is passed to); it is
            returned. Default: a fresh status in the physics' hand shape.

        Raises
        ------
        ValueError
            Non-finite set-points or a non-positive substep count.
        PhysicsError
            On divergence with ``strict=True``.
        """
        u = np.asarray(setpoint, dtype=np.float64)
        if u.shape != self._u.shape:
            if u.shape != (2,) or self._batched:
                hand = self._u.shape if self._batched else (2,)
                raise ValueError(f"setpoint must have shape {hand} (got {np.shape(setpoint)})")
            u = u.reshape(1, 2)
        n = int(n_substeps)
        if n < 1:
            raise ValueError(f"n_substeps must be >= 1 (got {n_substeps!r})")
        if skip is not None and not (isinstance(skip, np.ndarray) and skip.dtype == np.bool_
                                     and skip.shape == (self._n,)):
            raise ValueError(f"skip must be a bool array of shape ({self._n},)")
        status = StepStatus.empty(self._n) if out is None else out
        flags, diag = status._flags, status._diag
        ros2 = self._integrator == "ros2"
        if self._n == 1 and (skip is None or not skip[0]):
            ok = _step_on_this_thread(
                u, self._y, self._u, self._prm, self._time, n, ros2, self._ros2_dt,
                self.ch_limit, self.dn_limit, self.base_limit,
                flags, diag, status._failed, status._grasped, status._reason,
            )
        else:
            choice = self._dispatch
            parallel = choice is not None and choice.next()
            t0 = time.perf_counter()
            skipped = self._no_skip if skip is None else skip
            if parallel:  # three compiled calls (see _step_batch), the same numbers
                ok = _prepare_step(u, self._u, self._y, self._y_prev, flags, diag, skipped)
                if ok:
                    if ros2:
                        rosenbrock.advance_batch_parallel(self._y, self._u, self._prm, n,
                                                          self._ros2_dt, self.ch_limit, diag,
                                                          flags)
                    else:
                        kernel.advance_batch_parallel(self._y, self._u, self._prm, n,
                                                      self.ch_limit, diag, flags)
                    _finish_step(flags, self._y, self._y_prev, self._prm, diag, self._time,
                                 self.ch_limit, self.dn_limit, self.base_limit,
                                 status._failed, status._grasped, status._reason)
            else:
                ok = _step_batch(u, self._y, self._u, self._prm, self._time, self._y_prev,
                                 skipped, n, ros2, self._ros2_dt, self.ch_limit,
                                 self.dn_limit, self.base_limit, flags, diag, status._failed,
                                 status._grasped, status._reason)
            if ok and choice is not None:
                choice.record(parallel, time.perf_counter() - t0,
                              self._n if skip is None else self._n - np.count_nonzero(skip))
        if not ok:
            raise ValueError(f"setpoint must be finite (got {np.asarray(setpoint).tolist()})")
        if out is None and not self._batched:
            status = StepStatus(flags, diag, status._failed, status._grasped, status._reason,
                                batched=False)
        if strict and np.any(flags & (kernel.FLAG_NONFINITE | kernel.FLAG_CONSTRAINT)):
            raise PhysicsError(
                f"simulation diverged at t = {float(self._time.max()):.4f} s: "
                f"{', '.join(status.reasons)}",
                int(np.bitwise_or.reduce(flags)),
            )
        return status

    # ------------------------------------------------------------------------ read-outs
    @property
    def object_pose(self) -> np.ndarray:
        """Object (x, y, theta) in m, m, rad, shape (3,) or (N, 3)."""
        return self._out(self._y[:, X_OBJ : X_OBJ + 3])

    @property
    def object_velocity(self) -> np.ndarray:
        """Object (dx/dt, dy/dt, dtheta/dt) in m/s, m/s, rad/s, shape (3,) or (N, 3)."""
        return self._out(self._y[:, NQ + X_OBJ : NQ + X_OBJ + 3])

    @property
    def finger_angles(self) -> np.ndarray:
        """Joint angles (theta_1, theta_2) in rad, shape (2,) or (N, 2)."""
        return self._out(self._y[:, TH_1 : TH_1 + 2])

    @property
    def finger_velocities(self) -> np.ndarray:
        """Joint velocities in rad/s, shape (2,) or (N, 2)."""
        return self._out(self._y[:, NQ + TH_1 : NQ + TH_1 + 2])

    @property
    def deformation(self) -> np.ndarray:
        """Fingertip deformations (d_n1, d_n2, d_t1, d_t2) in m, shape (4,) or (N, 4)."""
        return self._out(self._y[:, DN_1 : DT_1 + 2])

    def readouts(self) -> HandReadouts:
        """Every named read-out of every hand at once, with the hand axis (N, ...) also for a
        one-hand physics (one copy of the states)."""
        read = np.empty((self._n, READ_SIZE))
        fill_readouts(self._y, self._u, self._prm, read)
        return HandReadouts.of_block(read)

    def read_into(self, read: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Write the read-outs of every hand, or of the hands ``rows`` (int (K,)), into the
        block ``read`` (N, :data:`READ_SIZE`, float64; :meth:`HandReadouts.of_block` names
        its columns): what the environments read per step, without a fresh block."""
        if rows is None:
            fill_readouts(self._y, self._u, self._prm, read)
        else:
            fill_readout_rows(self._y, self._u, self._prm, rows, read)

    def step_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The arrays a compiled step works on in place (:func:`_step_on_this_thread`): the
        states (N, 20), set-points (N, 2) (rad), packed parameters (N, N_PARAMS) and times
        (N,) (s)."""
        return self._y, self._u, self._prm, self._time

    @property
    def constraint_error(self) -> np.ndarray:
        """max |C^H| (m) and max |C^N| (m/s) over the two fingers at the current states,
        shape (2,) or (N, 2)."""
        out = self.constraint_errors(np.arange(self._n))
        return out if self._batched else out[0]

    def constraint_errors(self, rows: np.ndarray) -> np.ndarray:
        """:attr:`constraint_error` of the hands ``rows`` (int array (K,)), shape (K, 2), in
        one compiled call."""
        out = np.empty((len(rows), 2))
        _constraint_errors(self._y, self._prm, np.asarray(rows, dtype=np.int64), out)
        return out

    @property
    def joint_torques(self) -> np.ndarray:
        """PID joint torques (N m) of Eq 5.42 for the current set-points, shape (2,) or (N, 2)."""
        tau = np.empty((self._n, 2))
        pid_torques_batch(self._y, self._u, self._prm, tau)
        return tau if self._batched else tau[0]

    def diagnostics(self, setpoint: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Constraint residuals, PID torques and constraint forces of the first hand.

        Returns a dict with ``C_H`` (m, (2,)), ``C_N`` (m/s, (2,)), ``torque`` (N m, (2,)) for
        ``setpoint`` (default: the last one) and ``lambda`` (N, (4,): normal 1, 2, tangential
        1, 2).
        """
        u = self._u[0] if setpoint is None else np.asarray(setpoint, dtype=np.float64)
        dy = np.empty(NY)
        diag = np.empty(N_DIAG)
        csm_rhs(self._y[0], u, self._prm[0], dy, diag)
        return {
            "C_H": diag[0:2].copy(),
            "C_N": diag[2:4].copy(),
            "torque": diag[4:6].copy(),
            "lambda": diag[6:10].copy(),
        }

    def pid_torques(self, setpoint: np.ndarray | None = None) -> np.ndarray:
        """PID joint torques (N m) of Eq 5.42 of the first hand, shape (2,)."""
        return self.diagnostics(setpoint)["torque"]


__all__ = [
    "HandPhysics",
    "HandReadouts",
    "PhysicsError",
    "READ_SIZE",
    "StepStatus",
    "check_rk4_stability",
    "describe_flags",
    "rk4_stability_margins",
    "warn_if_unstable",
]
