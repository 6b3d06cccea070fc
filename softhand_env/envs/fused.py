"""The control step of one episode in one compiled call, and the compiled bookkeeping of a batch.

:meth:`~softhand_env.envs.transition.EpisodeBatch.step` of a single episode (the single
environment) runs the compiled pieces of a control step in one call of :func:`control_step`
instead of one Python-dispatched call each (every dispatch costs about a microsecond, about a
twentieth of a ROS2 control step)::

    action -> set-points          (envs.actions.ActionMap.setpoints' map; with set-point
                                  latency the ones commanded L steps ago,
                                  envs.actions.delay_setpoints)
           -> physics step        (physics.HandPhysics.step for one hand), or the pieces
                                  of the slip windows, cut at a set-point ramp's stairs
                                  (envs.windows.SlipWindows.step)
           -> contact check       (physics.friction.check_contact)
           -> read-outs           (physics.hand.fill_readouts)
           -> validated box       (physics.validity.validated_rows)
           -> observation frame   (envs.observation.observe_rows; ideal sensors only: a
                                  sensor model draws from the generator first)
           -> reward, success     (envs.tasks.score_rows, goal tasks)

Each piece is the same compiled function the batched path calls, on the same arrays, so the
numbers are bit for bit those of the batched path (``tests/envs/test_one_episode_step.py``).
The batched path (:meth:`~softhand_env.envs.transition.EpisodeBatch.step`) runs what follows
the physics step of N hands in :func:`finish_step` (the step recorded by :func:`record_step`:
status, contact check, read-outs, validated box, as the single episode's step records it; then
score, endings and observation frames) and starts episodes with :func:`write_starts` and
:func:`finish_rows`.
The arguments that stay the same over an episode batch's life (constants and the arrays
written in place) travel in one :class:`Arguments` record (:func:`control_step_packed`):
dispatching 49 arguments cost about 5 us a step, one record about 1 us.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.experimental import structref

from softhand_env.envs.actions import _map_setpoints, delay_setpoints
from softhand_env.envs.observation import observe_rows
from softhand_env.envs.tasks import score_rows
from softhand_env.envs.windows import _account
from softhand_env.physics import (
    failure,
    friction,
    jit_cache,  # noqa: F401  (the package stamp on cached kernels)
    validity,
)
from softhand_env.physics.hand import (
    READ_SETPOINT,
    READ_TORQUE,
    REASON_NAMES,
    _constraint_errors,
    _step_on_this_thread,
    fill_readout_rows,
    fill_readouts,
)
from softhand_env.physics.kernel import IMPULSE_OFFSET
from softhand_env.physics.model import DN_1, DN_2, DT_1, NQ, TH_1, X_OBJ

#: Ending code of an episode -> ``info["termination_reason"]``: 0 running (None), then the
#: physics' failure codes (:data:`~softhand_env.physics.hand.REASON_NAMES`), then a contact
#: that ended the episode (slip, or tension where a finger pulled) and success.
ENDING_NAMES = np.array((*REASON_NAMES, "slip", "tension", "success"), dtype=object)
ENDING_SLIP = len(REASON_NAMES)
ENDING_TENSION = ENDING_SLIP + 1
ENDING_SUCCESS = ENDING_SLIP + 2


@njit(cache=True)
def shift_history(OBS, frame, history):
    """Shift the observation history of every row of OBS (N, size) one frame older, in place:
    of its first ``history`` entries, frames of ``frame`` entries, newest first; the newest
    slot keeps its old values until written."""
    for s in range(OBS.shape[0]):
        for j in range(history - 1, frame - 1, -1):
            OBS[s, j] = OBS[s, j - frame]


@njit(cache=True)
def spread_frame(OBS, ROWS, frame, copies):
    """Copy the newest frame (the first ``frame`` entries) of the rows ROWS (int (K,)) of OBS
    (N, size) into their ``copies - 1`` older history slots, in place (``copies`` 1: none)."""
    for k in range(ROWS.shape[0]):
        s = ROWS[k]
        for c in range(1, copies):
            for j in range(frame):
                OBS[s, c * frame + j] = OBS[s, j]


@njit(cache=True)
def observe_read(READ, tactile, OBS):
    """The newest frame of ideal sensors (:func:`~softhand_env.envs.observation.observe_rows`;
    ``tactile``: with the deformations) of every row of the read-outs READ (N,
    ``READ_SIZE``) into the first columns of OBS (N, size)."""
    observe_rows(READ[:, TH_1 : TH_1 + 2], READ[:, NQ + TH_1 : NQ + TH_1 + 2],
                 READ[:, READ_SETPOINT : READ_SETPOINT + 2],
                 READ[:, READ_TORQUE : READ_TORQUE + 2], READ[:, DN_1 : DT_1 + 2], tactile,
                 OBS)


@njit(cache=True)
def control_step(A, PREV, READ, ros2, H, kind, max_delta, mid, half, low, high, CMD, CTRL,
                 SENT, LATENCY, APPLIED, Y, U, PRM, TIME, n, ch_limit, dn_limit, base_limit,
                 FLAGS, DIAG, FAILED, GRASPED, REASON, MU, NO_SKIP,
                 window, stop, LEFT, WIN_IMPULSE, ACTIVE, DONE, SUB, ramp, stair, START,
                 TARGET, OUT_FLAGS, OUT_ERROR, OUT_FAILED, OUT_GRASPED, OUT_REASON,
                 IMPULSE, RATIO, TENSION, CONTACT,
                 RADIUS, VALIDATED, observe, tactile, OBS, frame, history,
                 score, GOAL, INDEX, TOLERANCE, SCALE, WEIGHTS, FAILED_ONE, TERMS, SUCCESS,
                 REWARD, ROW):
    """One control step of one hand (arrays with a leading axis of 1), in place.

    Action map: actions A (1, 2), previous set-points PREV (1, 2) (rad), the map's constants
    (``kind``, ``max_delta``, ``mid``, ``half``, ``low``, ``high``; rad) into the commanded
    set-points CMD (1, 2) and the control cost CTRL (1,). Set-point latency (SENT (1, K, 2)
    with K > 0: the set-points commanded in the last K steps, newest first, PREV its first
    slot; LATENCY (1,) the episode's latency L in steps): the physics gets the set-points
    commanded L steps ago (APPLIED (1, 2)), as
    :meth:`~softhand_env.envs.transition.EpisodeBatch.step` applies them. Physics: the arrays of
    :meth:`~softhand_env.physics.HandPhysics.step_arrays` (Y, U, PRM, TIME), ``n``
    substeps, ``ros2`` and its step ``H`` (s), the limits; the status of a physics step into
    FLAGS, DIAG, FAILED, GRASPED, REASON (:class:`~softhand_env.physics.StepStatus`'
    arrays). ``window`` > 0: slip windows of that many substeps (``stop``: a bad window ends
    the step; LEFT, WIN_IMPULSE the :class:`~softhand_env.envs.windows.SlipWindows` state;
    ACTIVE, DONE, SUB scratch; ``ramp`` > 0: the set-points move from the physics' current
    ones to the command over the first ``ramp`` substeps in stairs of ``stair`` substeps, as
    :meth:`~softhand_env.envs.windows.SlipWindows.step` moves them, START and TARGET (1, 2)
    scratch), else the contact check of the step against MU (NO_SKIP all False). The step's
    outcome: OUT_FLAGS, OUT_ERROR (1, 2), OUT_FAILED, OUT_GRASPED,
    OUT_REASON (failure code), IMPULSE (1, 4) (N s), RATIO (1, 2), TENSION (1, 2), CONTACT
    (1,) (slip or tension). Read-outs into READ (1, ``READ_SIZE`` of
    :mod:`softhand_env.physics.hand`), the validated box (fingertip radius RADIUS (1,)) into
    VALIDATED (1, 2), and with ``observe`` the newest frame (``frame`` entries) into OBS
    (1, size) after shifting its ``history`` entries. The step's failure with slip and tension
    when they end the episode (``stop``) into FAILED_ONE (1,); with ``score`` (a goal task)
    the task's terms, success and reward (:func:`~softhand_env.envs.tasks.score_rows` of the
    goal GOAL (1, goal_dim) and the task's INDEX, TOLERANCE, SCALE, WEIGHTS; ROW = [0]) into
    TERMS (4, 1), SUCCESS (1,), REWARD (1,).

    Returns False, with nothing changed, if the action is not finite.
    """
    if not _map_setpoints(A, PREV, kind, max_delta, mid, half, low, high, CMD, CTRL):
        return False
    SRC = CMD
    if SENT.shape[1] > 0:
        delay_setpoints(CMD, SENT, LATENCY, APPLIED)
        SRC = APPLIED
    if window > 0:
        OUT_FLAGS[0] = 0
        OUT_ERROR[0, :] = 0.0
        OUT_FAILED[0] = False
        OUT_GRASPED[0] = False
        OUT_REASON[0] = 0
        IMPULSE[0, :] = 0.0
        RATIO[0, :] = 0.0
        TENSION[0, :] = False
        CONTACT[0] = False
        ACTIVE[0] = True
        DONE[0] = 0
        START[0, 0] = U[0, 0]
        START[0, 1] = U[0, 1]
        while True:  # SlipWindows.step for one hand
            piece = min(n - DONE[0], LEFT[0])
            PIECE_SRC = SRC
            if ramp > 0 and DONE[0] < ramp:  # cut at the stair ends; a stair's share
                piece = min(piece, stair - DONE[0] % stair)
                share = min((DONE[0] // stair + 1) * stair / ramp, 1.0)
                if share < 1.0:
                    for j in range(2):
                        TARGET[0, j] = START[0, j] + (SRC[0, j] - START[0, j]) * share
                    PIECE_SRC = TARGET
            if not (ACTIVE[0] and piece > 0):
                break
            _step_on_this_thread(PIECE_SRC, Y, U, PRM, TIME, piece, ros2, H, ch_limit,
                                 dn_limit, base_limit, FLAGS, DIAG, FAILED, GRASPED, REASON)
            OUT_FAILED[0] = FAILED[0]
            OUT_GRASPED[0] = GRASPED[0]
            OUT_REASON[0] = REASON[0]
            SUB[0] = int(DIAG[0, 2])
            _account(ACTIVE, FLAGS, DIAG[:, :2], DIAG[:, IMPULSE_OFFSET : IMPULSE_OFFSET + 4],
                     SUB, MU, stop, window, LEFT, WIN_IMPULSE, OUT_FAILED, ACTIVE, DONE,
                     OUT_FLAGS, OUT_ERROR, IMPULSE, RATIO, TENSION, CONTACT)
    else:
        _step_on_this_thread(SRC, Y, U, PRM, TIME, n, ros2, H, ch_limit, dn_limit,
                             base_limit, FLAGS, DIAG, FAILED, GRASPED, REASON)
    record_step(window == 0, FLAGS, DIAG, FAILED, GRASPED, REASON, MU, NO_SKIP, Y, U, PRM,
                READ, RADIUS, VALIDATED, OUT_FLAGS, OUT_ERROR, OUT_FAILED, OUT_GRASPED,
                OUT_REASON, IMPULSE, RATIO, TENSION, CONTACT)
    if observe:
        shift_history(OBS, frame, history)
        observe_read(READ, tactile, OBS)
    FAILED_ONE[0] = OUT_FAILED[0] or (stop and CONTACT[0])
    if score:
        score_rows(READ[:, X_OBJ : X_OBJ + 3], GOAL, CTRL, FAILED_ONE, OUT_GRASPED, ROW, INDEX,
                   TOLERANCE, SCALE, WEIGHTS, TERMS, SUCCESS, REWARD)
    return True


@njit(cache=True)
def record_step(outcome, FLAGS, DIAG, FAILED, GRASPED, REASON, MU, SKIP, Y, U, PRM, READ,
                RADIUS, VALIDATED, OUT_FLAGS, OUT_ERROR, OUT_FAILED, OUT_GRASPED, OUT_REASON,
                IMPULSE, RATIO, TENSION, CONTACT):
    """After a physics step of N hands, in one compiled call: with ``outcome`` (a step
    without slip windows, whose accounting writes these itself) the physics' status FLAGS,
    DIAG, FAILED, GRASPED, REASON (:class:`~softhand_env.physics.StepStatus`' arrays) into
    OUT_FLAGS, OUT_ERROR (N, 2) (max |C^H| in m, max |C^N| in m/s), OUT_FAILED,
    OUT_GRASPED, OUT_REASON (failure code), and the contact check against MU (N,) (hands of
    SKIP, bool (N,), never flagged) into IMPULSE (N, 4) (N s), RATIO (N, 2), TENSION (N, 2),
    CONTACT (N,) (:func:`~softhand_env.physics.friction.check_contact`); always the
    read-outs of the states Y, set-points U, parameters PRM into READ (N, ``READ_SIZE``)
    and the validated box (fingertip radius RADIUS (N,)) into VALIDATED (N, 2)."""
    if outcome:
        for s in range(FLAGS.shape[0]):
            OUT_FLAGS[s] = FLAGS[s]
            OUT_ERROR[s, 0] = DIAG[s, 0]
            OUT_ERROR[s, 1] = DIAG[s, 1]
            OUT_FAILED[s] = FAILED[s]
            OUT_GRASPED[s] = GRASPED[s]
            OUT_REASON[s] = REASON[s]
        friction.check_contact(DIAG[:, IMPULSE_OFFSET : IMPULSE_OFFSET + 4], MU, FAILED,
                               SKIP, IMPULSE, RATIO, TENSION, CONTACT)
    fill_readouts(Y, U, PRM, READ)
    validity.validated_rows(READ[:, DN_1 : DT_1 + 2], READ[:, TH_1 : TH_1 + 2],
                            READ[:, X_OBJ : X_OBJ + 3], RADIUS, VALIDATED)


@njit(cache=True)
def finish_step(outcome, SKIP, STEP_FAILED, STEP_GRASPED, STEP_CONTACT, CTRL, READ,
                on_success, frames, TERMINATED, S):
    """After the physics step of N hands, the rest of a batched control step in one compiled
    call, with the record S (:class:`Arguments` of the batch's arrays, ``FAILED_ONE`` (N,)
    and ``ROW`` every row): :func:`record_step` (``outcome``: a step without slip windows;
    SKIP bool (N,) the hands not stepped; read-outs into READ); the step's failure with slip
    and tension when they end the episode (``S.stop``) from STEP_FAILED, STEP_CONTACT (N,)
    into ``S.FAILED_ONE``; the task's terms, success and reward (a goal task:
    :func:`~softhand_env.envs.tasks.score_rows` with the control cost CTRL (N,) and the grasp
    STEP_GRASPED (N,); otherwise no success and no reward); TERMINATED (N,) (a failure, or
    success with ``on_success``); the ending codes (:func:`mark_endings`); the observation
    history shifted by one frame and, with ``frames`` (ideal sensors without noise), the
    newest frames written from READ."""
    record_step(outcome, S.FLAGS, S.DIAG, S.FAILED, S.GRASPED, S.REASON, S.MU, SKIP, S.Y,
                S.U, S.PRM, READ, S.RADIUS, S.VALIDATED, S.OUT_FLAGS, S.OUT_ERROR,
                S.OUT_FAILED, S.OUT_GRASPED, S.OUT_REASON, S.IMPULSE, S.RATIO, S.TENSION,
                S.CONTACT)
    failed = S.FAILED_ONE
    for s in range(failed.shape[0]):
        failed[s] = STEP_FAILED[s] or (S.stop and STEP_CONTACT[s])
    if S.score:
        score_rows(READ[:, X_OBJ : X_OBJ + 3], S.GOAL, CTRL, failed, STEP_GRASPED, S.ROW,
                   S.INDEX, S.TOLERANCE, S.SCALE, S.WEIGHTS, S.TERMS, S.SUCCESS, S.REWARD)
    else:
        S.SUCCESS[:] = False
        S.REWARD[:] = 0.0
    for s in range(failed.shape[0]):
        TERMINATED[s] = failed[s] or (on_success and S.SUCCESS[s])
    mark_endings(STEP_CONTACT, S.TENSION, TERMINATED, failed, S.stop, on_success,
                 S.OUT_REASON)
    shift_history(S.OBS, S.frame, S.history)
    if frames:
        observe_read(READ, S.tactile, S.OBS)


@njit(cache=True)
def restart_rows(Y, U, PRM, ROWS, READ, RADIUS, VALIDATED, ERROR, GRASPED, observe, tactile,
                 OBS):
    """The start-state bookkeeping of the hands ROWS (int (K,)) just restarted, in one compiled
    call: their read-outs into READ (N, ``READ_SIZE``), validated box (fingertip radius
    RADIUS (N,)) into VALIDATED (N, 2), max |C^H| (m) and max |C^N| (m/s) into ERROR (N, 2),
    grasp (:func:`~softhand_env.physics.failure.holds`) into GRASPED (N,), and with
    ``observe`` (ideal sensors) the newest frame (``tactile``: with the deformations) into the
    first columns of OBS (N, size). The other rows are left as they are."""
    fill_readout_rows(Y, U, PRM, ROWS, READ)
    for k in range(ROWS.shape[0]):
        s = ROWS[k]
        r = READ[s : s + 1]
        validity.validated_rows(r[:, DN_1 : DT_1 + 2], r[:, TH_1 : TH_1 + 2],
                                r[:, X_OBJ : X_OBJ + 3], RADIUS[s : s + 1],
                                VALIDATED[s : s + 1])
        _constraint_errors(Y, PRM, ROWS[k : k + 1], ERROR[s : s + 1])
        GRASPED[s] = failure.holds(READ[s, DN_1], READ[s, DN_2])
        if observe:
            observe_read(r, tactile, OBS[s : s + 1])


@njit(cache=True)
def finish_rows(Y, U, PRM, ROWS, READ, RADIUS, VALIDATED, ERROR, GRASPED, observe, tactile,
                OBS, frame, copies, score, GOAL, INDEX, TOLERANCE, SCALE, WEIGHTS, ZERO, FALSE,
                TERMS, SUCCESS, REWARD, GOAL_SCALE, bound):
    """The start-state bookkeeping and first observation of the episodes ROWS (int (K,)) just
    started, in one compiled call: :func:`restart_rows` (read-outs, validated box, constraint
    errors, grasp; with ``observe`` the newest frame of ideal sensors), the start state scored
    (with ``score``, a goal task: :func:`~softhand_env.envs.tasks.score_rows` with no control
    cost ZERO (N,) and no failure FALSE (N,), the goal GOAL (N, goal_dim) and the task's INDEX,
    TOLERANCE, SCALE, WEIGHTS; the terms into the scratch TERMS (4, N) and REWARD (N,),
    success into SUCCESS (N,); otherwise SUCCESS False and REWARD 0 on ROWS), the goal
    observation (GOAL / GOAL_SCALE (goal_dim,) clipped to +-``bound``) into the last goal_dim
    columns of OBS, and the newest frame (``frame`` entries) copied into the ``copies - 1``
    older history slots (``copies`` 1: none). The other rows are left as they are."""
    restart_rows(Y, U, PRM, ROWS, READ, RADIUS, VALIDATED, ERROR, GRASPED, observe, tactile,
                 OBS)
    if score:
        score_rows(READ[:, X_OBJ : X_OBJ + 3], GOAL, ZERO, FALSE, GRASPED, ROWS, INDEX,
                   TOLERANCE, SCALE, WEIGHTS, TERMS, SUCCESS, REWARD)
    else:
        for k in range(ROWS.shape[0]):
            SUCCESS[ROWS[k]] = False
            REWARD[ROWS[k]] = 0.0
    at = OBS.shape[1] - GOAL.shape[1]
    for k in range(ROWS.shape[0]):
        s = ROWS[k]
        for t in range(GOAL.shape[1]):
            OBS[s, at + t] = min(max(GOAL[s, t] / GOAL_SCALE[t], -bound), bound)
    spread_frame(OBS, ROWS, frame, copies)


@njit(cache=True)
def write_starts(ROWS, SETPOINTS, LAT, GOALS, MUS, RADII, LATENCY, SENT, GOAL, MU, RADIUS,
                 TERMS, FLAGS, IMPULSE, RATIO, TENSION, ENDING):
    """The episode batch's arrays of the episodes ROWS (int (K,)) just started, in one
    compiled call: row k's latency LAT[k] (control steps), every earlier command SENT (N, L,
    2) = its first set-points SETPOINTS[k] (rad), goal GOALS[k] (SI), friction coefficient
    MUS[k] and fingertip radius RADII[k] (m) into LATENCY, SENT, GOAL, MU, RADIUS; the
    reward TERMS (T, N), FLAGS, contact IMPULSE (N, 4), friction RATIO (N, 2), TENSION
    (N, 2) and ending code ENDING (N,) of those rows cleared. The other rows are left as they
    are."""
    for k in range(ROWS.shape[0]):
        s = ROWS[k]
        ENDING[s] = 0
        LATENCY[s] = LAT[k]
        for j in range(SENT.shape[1]):
            SENT[s, j, 0] = SETPOINTS[k, 0]
            SENT[s, j, 1] = SETPOINTS[k, 1]
        for t in range(GOAL.shape[1]):
            GOAL[s, t] = GOALS[k, t]
        MU[s] = MUS[k]
        RADIUS[s] = RADII[k]
        for t in range(TERMS.shape[0]):
            TERMS[t, s] = 0.0
        FLAGS[s] = 0
        for j in range(4):
            IMPULSE[s, j] = 0.0
        for f in range(2):
            RATIO[s, f] = 0.0
            TENSION[s, f] = False


@njit(cache=True)
def mark_endings(CONTACT, TENSION, TERMINATED, FAILED, on_contact, on_success, ENDING):
    """The ending codes ENDING (N,) of a step whose failure codes it already holds (0 or a
    code of :data:`~softhand_env.physics.hand.REASON_NAMES`), in one compiled call: with
    ``on_contact`` (slip and tension end episodes) a CONTACT (N,) row becomes
    :data:`ENDING_TENSION` if a finger pulled (TENSION (N, 2)), else :data:`ENDING_SLIP`; with
    ``on_success`` a TERMINATED (N,) row without FAILED (N,) (slip and tension included when
    they end episodes) becomes :data:`ENDING_SUCCESS`."""
    for s in range(ENDING.shape[0]):
        if on_contact and CONTACT[s]:
            ENDING[s] = ENDING_TENSION if (TENSION[s, 0] or TENSION[s, 1]) else ENDING_SLIP
        if on_success and TERMINATED[s] and not FAILED[s]:
            ENDING[s] = ENDING_SUCCESS


@structref.register
class _ArgumentsType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Arguments(structref.StructRefProxy):
    """The arguments of :func:`control_step` after the integrator pair, in one compiled record
    (:func:`pack_arguments`): the arrays are the caller's (shared, not copied), so that one
    step passes one object instead of 49 (each dispatched argument costs a fraction of a
    microsecond). Not picklable: rebuild it from the arguments."""


#: The fields of :class:`Arguments`, the parameters of :func:`control_step` after ``H``.
ARGUMENT_FIELDS = (
    "kind", "max_delta", "mid", "half", "low", "high", "CMD", "CTRL", "SENT", "LATENCY",
    "APPLIED", "Y", "U", "PRM", "TIME", "n", "ch_limit", "dn_limit", "base_limit", "FLAGS",
    "DIAG", "FAILED", "GRASPED", "REASON",
    "MU", "NO_SKIP", "window", "stop", "LEFT", "WIN_IMPULSE", "ACTIVE", "DONE", "SUB",
    "ramp", "stair", "START", "TARGET", "OUT_FLAGS", "OUT_ERROR", "OUT_FAILED", "OUT_GRASPED",
    "OUT_REASON", "IMPULSE", "RATIO",
    "TENSION", "CONTACT", "RADIUS", "VALIDATED", "observe", "tactile", "OBS", "frame",
    "history", "score", "GOAL", "INDEX", "TOLERANCE", "SCALE", "WEIGHTS", "FAILED_ONE",
    "TERMS", "SUCCESS", "REWARD", "ROW",
)
structref.define_proxy(Arguments, _ArgumentsType, list(ARGUMENT_FIELDS))


@njit(cache=True)
def pack_arguments(kind, max_delta, mid, half, low, high, CMD, CTRL, SENT, LATENCY, APPLIED,
                   Y, U, PRM, TIME, n,
                   ch_limit, dn_limit, base_limit, FLAGS, DIAG, FAILED, GRASPED, REASON, MU,
                   NO_SKIP, window, stop, LEFT, WIN_IMPULSE, ACTIVE, DONE, SUB, ramp, stair,
                   START, TARGET, OUT_FLAGS, OUT_ERROR, OUT_FAILED, OUT_GRASPED, OUT_REASON,
                   IMPULSE, RATIO, TENSION,
                   CONTACT, RADIUS, VALIDATED, observe, tactile, OBS, frame, history,
                   score, GOAL, INDEX, TOLERANCE, SCALE, WEIGHTS, FAILED_ONE, TERMS, SUCCESS,
                   REWARD, ROW):
    """An :class:`Arguments` record of :func:`control_step`'s arguments after ``H`` (the
    arrays are shared with the caller)."""
    return Arguments(kind, max_delta, mid, half, low, high, CMD, CTRL, SENT, LATENCY, APPLIED,
                     Y, U, PRM, TIME, n,
                     ch_limit, dn_limit, base_limit, FLAGS, DIAG, FAILED, GRASPED, REASON, MU,
                     NO_SKIP, window, stop, LEFT, WIN_IMPULSE, ACTIVE, DONE, SUB, ramp,
                     stair, START, TARGET, OUT_FLAGS, OUT_ERROR, OUT_FAILED, OUT_GRASPED,
                     OUT_REASON, IMPULSE, RATIO, TENSION,
                     CONTACT, RADIUS, VALIDATED, observe, tactile, OBS, frame, history,
                     score, GOAL, INDEX, TOLERANCE, SCALE, WEIGHTS, FAILED_ONE, TERMS, SUCCESS,
                     REWARD, ROW)


@njit(cache=True)
def control_step_packed(A, PREV, READ, ros2, H, S):
    """:func:`control_step` with the arguments after ``H`` from the record S
    (:class:`Arguments`)."""
    return control_step(A, PREV, READ, ros2, H, S.kind, S.max_delta, S.mid, S.half, S.low,
                        S.high, S.CMD, S.CTRL, S.SENT, S.LATENCY, S.APPLIED, S.Y, S.U,
                        S.PRM, S.TIME, S.n, S.ch_limit,
                        S.dn_limit, S.base_limit, S.FLAGS,
                        S.DIAG, S.FAILED, S.GRASPED, S.REASON, S.MU, S.NO_SKIP, S.window,
                        S.stop, S.LEFT, S.WIN_IMPULSE, S.ACTIVE, S.DONE, S.SUB, S.ramp,
                        S.stair, S.START, S.TARGET, S.OUT_FLAGS,
                        S.OUT_ERROR, S.OUT_FAILED, S.OUT_GRASPED, S.OUT_REASON, S.IMPULSE,
                        S.RATIO, S.TENSION, S.CONTACT, S.RADIUS, S.VALIDATED, S.observe,
                        S.tactile, S.OBS, S.frame, S.history, S.score, S.GOAL, S.INDEX,
                        S.TOLERANCE, S.SCALE, S.WEIGHTS, S.FAILED_ONE, S.TERMS, S.SUCCESS,
                        S.REWARD, S.ROW)
