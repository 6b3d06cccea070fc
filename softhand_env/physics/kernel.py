"""Compiled RK4 kernels that advance the CSM model many 0.1 ms substeps per call.

* :func:`advance` integrates one system ``n`` classic-RK4 substeps with constant set-points,
  tracks the largest constraint residuals seen and stops at the first invalid state.
* :func:`advance_batch` does the same for ``N`` independent systems in parallel (numba
  ``prange`` over blocks of :data:`LANES` systems, each block integrated in SIMD lanes, see
  "lane kernel" below); each system may have its own parameter vector. Every system ends
  bit for bit as :func:`advance` would leave it.

Status flags (bitwise OR, returned per system):

=====================  =====  ==========================================================
flag                   value  meaning
=====================  =====  ==========================================================
``FLAG_NONFINITE``     1      NaN or inf in the state (fatal)
``FLAG_CONSTRAINT``    2      max |C^H| above ``ch_limit`` (fatal, default 1e-3 m)
``FLAG_LOST``          4      a normal deformation d_n < 0: the grasp is lost (fatal: the
                              bilateral constraint would pull the object)
``FLAG_OVERCOMPRESSED`` 8     a normal deformation d_n >= the stop limit ``prm[P_DN_STOP]``
                              (default a; fatal: outside the model or past the caller's
                              over-compression limit)
``FLAG_BASE``          16     the contact circle passed the fingertip base,
                              tan(theta_p) > (a - d_n)/a_c, where the closed-form energy
                              over-predicts (not fatal; checked at the end of the call); also
                              raised, and integration stopped, at the first substep whose
                              reach past the base exceeds ``prm[P_BASE_STOP]`` (default inf)
``FLAG_SKIP``          32     input only: :func:`advance_batch` leaves this system alone
                              (e.g. an environment that restarts this step)
=====================  =====  ==========================================================

Integration stops at the substep where a fatal flag is raised, leaving the state at that
substep; the number of substeps actually taken is returned.

Stop limits (the last entries of the packed parameters, :func:`.model.with_stop_limits`):
after every substep the state is tested against ``prm[P_DN_STOP]`` (d_n, m; default a),
``prm[P_BASE_STOP]`` (reach past the fingertip base, :func:`.contact.beyond_base`; default
inf = never) and ``prm[P_CH_STOP]`` (|C^H|, m; default inf = never), and the call stops at
the first substep beyond one of them with ``FLAG_OVERCOMPRESSED``, ``FLAG_BASE`` or
``FLAG_CONSTRAINT``. The residual |C^H| of a state is evaluated by the first RK4 stage of the
substep that starts from it, so a constraint stop comes one substep (0.1 ms) after the first
state beyond ``P_CH_STOP``; the other limits stop on the offending state itself. With the
defaults (what :func:`.model.pack_params` packs) a call behaves as it always has: it stops
only at d_n >= a, non-finite states and lost grasps, and ``ch_limit`` and the base are
judged at the end of the call. The cheap per-substep test (:func:`_maybe_fatal`) is a
superset of the exact one (:func:`_stop_flags`), which runs only when it fires.

Diagnostics of a call (``diag``, one row per system in the batch):

=====  =============================================================================
entry  content
=====  =============================================================================
0      largest |C^H| (m) over the states visited
1      largest |C^N| (m/s) over the states visited
2      substeps taken (a row of at least 3 entries)
3-4    normal contact impulses J_n1, J_n2 (N s; integral of the holonomic multipliers
       lambda_H) over the substeps taken (a row of :data:`N_STEP_DIAG` = 7 entries)
5-6    tangential contact impulses J_t1, J_t2 (N s; integral of the rolling multipliers
       lambda_N) over the substeps taken (a row of 7 entries)
=====  =============================================================================

Each substep adds h/6 (lambda_1 + 2 lambda_2 + 2 lambda_3 + lambda_4) of its four RK4 stages
to the impulses: the quadrature with which RK4 applies those forces to the momenta, so the
impulse is exactly what the integrator transferred through the contact. Shorter rows receive
the entries they have room for (2: residuals only; 3: residuals and substeps).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.contact import beyond_base
from softhand_env.physics.model import (
    _FASTMATH,
    DN_1,
    N_DIAG,
    N_PARAMS,
    NY,
    P_A,
    P_BASE_STOP,
    P_CH_STOP,
    P_DN_STOP,
    P_DT,
    TH_1,
    TH_OBJ,
    csm_rhs,
    csm_terms,
)

FLAG_NONFINITE = 1
FLAG_CONSTRAINT = 2
FLAG_LOST = 4
FLAG_OVERCOMPRESSED = 8
FLAG_BASE = 16
FLAG_SKIP = 32
FATAL_FLAGS = FLAG_NONFINITE | FLAG_CONSTRAINT | FLAG_LOST | FLAG_OVERCOMPRESSED
#: Length of a ``diag`` row that receives the contact impulses (see the module docstring).
N_STEP_DIAG = 7
#: Offset of the contact impulses (J_n1, J_n2, J_t1, J_t2) in a diag row of N_STEP_DIAG entries.
IMPULSE_OFFSET = 3
# offset of the constraint forces (lambda_H1, lambda_H2, lambda_N1, lambda_N2) in csm_rhs's diag
_W_LAM = 6
#: Default bound on |C^H| (m) above which the state counts as diverged.
CH_LIMIT = 1e-3


@njit(cache=True)
def _rk4_substep(y, u, prm, h, k, work, imp):
    """One classic RK4 step of :func:`csm_rhs` in place; ``k`` is (5, NY) scratch, ``work`` the
    (N_DIAG,) diagnostics scratch; adds the step's contact impulses to ``imp`` (4,).

    Returns (|C^H|max, |C^N|max) evaluated at the state the step starts from (stage 1).
    """
    k1 = k[0]
    k2 = k[1]
    k3 = k[2]
    k4 = k[3]
    tmp = k[4]
    csm_rhs(y, u, prm, k1, work)
    ch = max(abs(work[0]), abs(work[1]))
    cn = max(abs(work[2]), abs(work[3]))
    l1 = (work[_W_LAM], work[_W_LAM + 1], work[_W_LAM + 2], work[_W_LAM + 3])
    for j in range(NY):
        tmp[j] = y[j] + 0.5 * h * k1[j]
    csm_rhs(tmp, u, prm, k2, work)
    l2 = (work[_W_LAM], work[_W_LAM + 1], work[_W_LAM + 2], work[_W_LAM + 3])
    for j in range(NY):
        tmp[j] = y[j] + 0.5 * h * k2[j]
    csm_rhs(tmp, u, prm, k3, work)
    l3 = (work[_W_LAM], work[_W_LAM + 1], work[_W_LAM + 2], work[_W_LAM + 3])
    for j in range(NY):
        tmp[j] = y[j] + h * k3[j]
    csm_rhs(tmp, u, prm, k4, work)
    for j in range(NY):
        y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    for j in range(4):
        imp[j] += h / 6.0 * (l1[j] + 2.0 * l2[j] + 2.0 * l3[j] + work[_W_LAM + j])
    return ch, cn


@njit(cache=True)
def _store_impulse(diag, imp):
    """Copy the impulses (4,) into entries 3-6 of ``diag`` if it has room for them."""
    if diag.shape[0] >= N_STEP_DIAG:
        for j in range(4):
            diag[IMPULSE_OFFSET + j] = imp[j]


@njit(cache=True)
def _state_flags(y, prm, ch, ch_limit):
    """Flags of state y given its holonomic residual ch: the fatal ones (non-finite, ch above
    ch_limit, d_n < 0, d_n >= ``prm[P_DN_STOP]``) and ``FLAG_BASE`` where a contact reaches
    past its base by more than ``prm[P_BASE_STOP]`` (tested only when that is finite)."""
    flags = 0
    for j in range(NY):
        if not math.isfinite(y[j]):
            return FLAG_NONFINITE
    if ch > ch_limit:
        flags |= FLAG_CONSTRAINT
    dn_stop = prm[P_DN_STOP]
    for i in range(2):
        dn = y[DN_1 + i]
        if dn < 0.0:
            flags |= FLAG_LOST
        elif dn >= dn_stop:
            flags |= FLAG_OVERCOMPRESSED
    base_stop = prm[P_BASE_STOP]
    if base_stop < math.inf and past_base(y, prm[P_A], base_stop):
        flags |= FLAG_BASE
    return flags


@njit(cache=True)
def _stop_flags(y, prm, ch_max, ch_limit):
    """Flags that stop integration at state y (the exact test after a substep): those of
    :func:`_state_flags` without the end-of-call ``ch_limit`` test, plus ``FLAG_CONSTRAINT``
    if the running max |C^H| ``ch_max`` exceeds ``prm[P_CH_STOP]``."""
    flags = _state_flags(y, prm, 0.0, ch_limit)
    if flags != FLAG_NONFINITE and ch_max > prm[P_CH_STOP]:
        flags |= FLAG_CONSTRAINT
    return flags


@njit(cache=True, fastmath=False)
def _suspect(y, prm, ch_max):
    """Cheap superset of ``_stop_flags(y, prm, ch_max, ...) != 0`` (see :func:`_maybe_fatal`)."""
    return _maybe_fatal(
        _state_sum(y, 0, 1), y[DN_1], y[DN_1 + 1], y[TH_1] - y[TH_OBJ],
        y[TH_1 + 1] + y[TH_OBJ], ch_max, prm[P_A], prm[P_DN_STOP], prm[P_BASE_STOP],
        prm[P_CH_STOP],
    )


@njit(cache=True, fastmath=False, inline="always")
def _state_sum(buf, start, stride):
    """Sum of the NY state entries ``buf[start + j * stride]`` in four partial sums (finite
    if every entry is; the order lets the compiler keep four independent additions)."""
    s0 = buf[start] + buf[start + 4 * stride]
    s1 = buf[start + stride] + buf[start + 5 * stride]
    s2 = buf[start + 2 * stride] + buf[start + 6 * stride]
    s3 = buf[start + 3 * stride] + buf[start + 7 * stride]
    for j in range(8, NY, 4):
        s0 += buf[start + j * stride]
        s1 += buf[start + (j + 1) * stride]
        s2 += buf[start + (j + 2) * stride]
        s3 += buf[start + (j + 3) * stride]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, fastmath=False, inline="always")
def _below_base(d, theta_p, a, limit):
    """True only if a contact of deformation d in [0, a) and angle theta_p (rad) is surely not
    past its base by more than ``limit`` (a superset test of :func:`.contact.beyond_base`
    without transcendental functions: |sin t| <= |t| and cos t >= 1 - t^2/2 turn
    ``a_c |sin t| > limit (a - d) cos t`` into a bound on t^2; limit = inf: always True for
    |t| < sqrt 2)."""
    t2 = theta_p * theta_p
    r = limit * ((a - d) * (1.0 - 0.5 * t2))
    return (r >= 0.0) & (d * (2.0 * a - d) * t2 <= r * r)


@njit(cache=True, fastmath=False, inline="always")
def _maybe_fatal(total, d1, d2, tp1, tp2, ch_max, a, dn_stop, base_stop, ch_stop):
    """False only if the state sum ``total`` is finite, both d_n are in [0, dn_stop), the
    running max |C^H| ``ch_max`` is at most ``ch_stop`` and neither contact (angles tp1, tp2)
    can be past its base by more than ``base_stop``: a cheap superset of the stop test (an
    overflowing sum of finite entries, or a contact near its base, only costs the exact
    one)."""
    return not (
        (total - total == 0.0) & (d1 >= 0.0) & (d1 < dn_stop) & (d2 >= 0.0) & (d2 < dn_stop)
        & (ch_max <= ch_stop) & _below_base(d1, tp1, a, base_stop)
        & _below_base(d2, tp2, a, base_stop)
    )


#: The past-the-base test compiled for the kernels (one source: :func:`contact.beyond_base`).
_beyond_base = njit(cache=True, inline="always")(beyond_base)


@njit(cache=True)
def past_base(y, a, limit):
    """True if a contact circle of state ``y`` (20,) reaches past its fingertip base by more
    than ``limit`` (1 = at the base, see :func:`softhand_env.physics.contact.beyond_base`); a finger
    with d_n outside (0, a) has no contact circle."""
    for i in range(2):
        dn = y[DN_1 + i]
        if dn <= 0.0 or dn >= a:
            continue
        sgn = -1.0 if i == 0 else 1.0
        if _beyond_base(dn, y[TH_1 + i] + sgn * y[TH_OBJ], a, limit):
            return True
    return False


@njit(cache=True)
def base_exceeded(y, prm):
    """True if a contact circle has passed its fingertip base (``FLAG_BASE``)."""
    return past_base(y, prm[P_A], 1.0)


@njit(cache=True)
def _finish(y, u, prm, ch_max, cn_max, ch_limit, diag, k, work):
    """End of a call that ran all its substeps: residuals of the final state (the next stage-1
    evaluation), the constraint and base flags; writes ``diag`` and returns the flags."""
    csm_rhs(y, u, prm, k[0], work)
    ch_max = max(ch_max, abs(work[0]), abs(work[1]))
    cn_max = max(cn_max, abs(work[2]), abs(work[3]))
    flags = _state_flags(y, prm, ch_max, ch_limit)
    if flags == 0 and base_exceeded(y, prm):
        flags = FLAG_BASE
    diag[0] = ch_max
    diag[1] = cn_max
    return flags


@njit(cache=True)
def _advance_one(y, u, prm, n, ch_limit, diag, k, work):
    h = prm[P_DT]
    ch_max = 0.0
    cn_max = 0.0
    flags = 0
    done = 0
    imp = np.zeros(4)
    for _ in range(n):
        ch, cn = _rk4_substep(y, u, prm, h, k, work, imp)
        ch_max = max(ch_max, ch)
        cn_max = max(cn_max, cn)
        done += 1
        if _suspect(y, prm, ch_max):
            flags = _stop_flags(y, prm, ch_max, ch_limit)
            if flags != 0:
                break
    if flags == 0:
        flags = _finish(y, u, prm, ch_max, cn_max, ch_limit, diag, k, work)
    else:
        diag[0] = ch_max
        diag[1] = cn_max
    if diag.shape[0] > 2:
        diag[2] = done
    _store_impulse(diag, imp)
    return flags, done


@njit(cache=True)
def advance(y, u, prm, n, ch_limit, diag):
    """Advance one system ``n`` RK4 substeps of ``prm[P_DT]`` seconds, in place.

    Parameters
    ----------
    y : ndarray, shape (20,), float64, modified in place
        State [q, p, z] (see :mod:`softhand_env.physics.model`).
    u : ndarray, shape (2,)
        Finger-angle set-points (rad), held constant over the call.
    prm : ndarray, shape (N_PARAMS,)
        Packed parameters (:func:`softhand_env.physics.model.pack_params`).
    n : int
        Number of substeps.
    ch_limit : float
        |C^H| (m) above which the state is flagged as diverged.
    diag : ndarray, shape (2,), (3,) or (N_STEP_DIAG,), output
        max |C^H| (m) and max |C^N| (m/s) over the states visited; a third entry, if present,
        receives the number of substeps taken; with N_STEP_DIAG = 7 entries, entries 3-6 also
        receive the contact impulses J_n1, J_n2, J_t1, J_t2 (N s) over the substeps taken
        (module doc).

    Returns
    -------
    flags : int
        Bitwise OR of the status flags (0 = valid).
    done : int
        Substeps actually taken (< n only when a fatal flag stopped integration).
    """
    k = np.empty((5, NY))
    work = np.zeros(N_DIAG)
    return _advance_one(y, u, prm, n, ch_limit, diag, k, work)


# ------------------------------------------------------------------------------ lane kernel
# The batched kernel integrates blocks of LANES systems at once in structure-of-arrays form:
# quantity j of lane l lives at [j * LANES + l] of a flat float64 array, so the loop over the
# lanes of :func:`_rhs_lanes` (the model's :func:`.model.csm_terms`, inlined) is
# a loop of unit-stride loads and stores that LLVM vectorises across systems (one AVX-512
# register = 8 lanes, 2 per block; 4 lanes per AVX2 register). The model's sin/cos is
# straight-line code (model.sincos): a libm call would stop the vectoriser. The arithmetic
# per system is the single-system kernel's: the same RHS source and the same RK4
# combinations in the same order, all in strict IEEE arithmetic, so each system of a batch
# ends bit for bit where :func:`advance` takes it (state, diag, flags and the substep of a
# fatal stop).

#: Systems per block of the batched kernel (SIMD lanes).
LANES = 16
# rows of the per-block parameter array: the packed parameters, then the two set-points
_R_U = N_PARAMS
_NPU = N_PARAMS + 2
# rows of a stage-derivative array: dy/dt (NY), then C^H (2) and C^N (2) of that stage, then
# the constraint forces lambda_H1, lambda_H2, lambda_N1, lambda_N2 of that stage
_R_RES = NY
_R_LAM = NY + 4
_NK = NY + 8
# blocks of at most this many systems run the single-system kernel instead (a lane costs
# ~1/4 of a scalar system; a half block of 8 lanes then costs more than 2 systems)
_SCALAR_MAX = 2


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _rhs_lanes(Yl, Pl, Kl, nl):
    """dy/dt and the residuals of lanes 0..nl-1: Yl (NY*LANES), Pl (_NPU*LANES) -> Kl
    (_NK*LANES)."""
    for l in range(nl):
        y = (
            Yl[0 * LANES + l], Yl[1 * LANES + l], Yl[2 * LANES + l], Yl[3 * LANES + l],
            Yl[4 * LANES + l], Yl[5 * LANES + l], Yl[6 * LANES + l], Yl[7 * LANES + l],
            Yl[8 * LANES + l], Yl[9 * LANES + l], Yl[10 * LANES + l], Yl[11 * LANES + l],
            Yl[12 * LANES + l], Yl[13 * LANES + l], Yl[14 * LANES + l], Yl[15 * LANES + l],
            Yl[16 * LANES + l], Yl[17 * LANES + l], Yl[18 * LANES + l], Yl[19 * LANES + l],
        )
        prm = (
            Pl[0 * LANES + l], Pl[1 * LANES + l], Pl[2 * LANES + l], Pl[3 * LANES + l],
            Pl[4 * LANES + l], Pl[5 * LANES + l], Pl[6 * LANES + l], Pl[7 * LANES + l],
            Pl[8 * LANES + l], Pl[9 * LANES + l], Pl[10 * LANES + l], Pl[11 * LANES + l],
            Pl[12 * LANES + l], Pl[13 * LANES + l], Pl[14 * LANES + l], Pl[15 * LANES + l],
            Pl[16 * LANES + l], Pl[17 * LANES + l], Pl[18 * LANES + l], Pl[19 * LANES + l],
            Pl[20 * LANES + l], Pl[21 * LANES + l], Pl[22 * LANES + l],
        )
        u = (Pl[_R_U * LANES + l], Pl[(_R_U + 1) * LANES + l])
        t = csm_terms(y, u, prm)
        Kl[0 * LANES + l] = y[9]
        Kl[1 * LANES + l] = y[10]
        Kl[2 * LANES + l] = y[11]
        Kl[3 * LANES + l] = y[12]
        Kl[4 * LANES + l] = y[13]
        Kl[5 * LANES + l] = y[14]
        Kl[6 * LANES + l] = y[15]
        Kl[7 * LANES + l] = y[16]
        Kl[8 * LANES + l] = y[17]
        Kl[9 * LANES + l] = t[0]
        Kl[10 * LANES + l] = t[1]
        Kl[11 * LANES + l] = t[2]
        Kl[12 * LANES + l] = t[3]
        Kl[13 * LANES + l] = t[4]
        Kl[14 * LANES + l] = t[5]
        Kl[15 * LANES + l] = t[6]
        Kl[16 * LANES + l] = t[7]
        Kl[17 * LANES + l] = t[8]
        Kl[18 * LANES + l] = t[9]
        Kl[19 * LANES + l] = t[10]
        Kl[(_R_RES + 0) * LANES + l] = t[11]
        Kl[(_R_RES + 1) * LANES + l] = t[12]
        Kl[(_R_RES + 2) * LANES + l] = t[13]
        Kl[(_R_RES + 3) * LANES + l] = t[14]
        Kl[(_R_LAM + 0) * LANES + l] = t[17]
        Kl[(_R_LAM + 1) * LANES + l] = t[18]
        Kl[(_R_LAM + 2) * LANES + l] = t[19]
        Kl[(_R_LAM + 3) * LANES + l] = t[20]


@njit(cache=True, error_model="numpy")
def _rk4_lanes(Yl, Pl, Hl, K1, K2, K3, K4, Tl, Il, nl):
    """One RK4 substep of every lane in place, with the combinations of :func:`_rk4_substep`;
    adds the contact impulses of the substep to ``Il`` (4*LANES).

    ``Hl`` (NY*LANES) holds each lane's step h in every row, so that the combinations are
    flat unit-stride loops over all LANES lanes (lanes >= nl have zero derivatives and stay).
    """
    _rhs_lanes(Yl, Pl, K1, nl)
    for i in range(NY * LANES):
        Tl[i] = Yl[i] + 0.5 * Hl[i] * K1[i]
    _rhs_lanes(Tl, Pl, K2, nl)
    for i in range(NY * LANES):
        Tl[i] = Yl[i] + 0.5 * Hl[i] * K2[i]
    _rhs_lanes(Tl, Pl, K3, nl)
    for i in range(NY * LANES):
        Tl[i] = Yl[i] + Hl[i] * K3[i]
    _rhs_lanes(Tl, Pl, K4, nl)
    for i in range(NY * LANES):
        Yl[i] += Hl[i] / 6.0 * (K1[i] + 2.0 * K2[i] + 2.0 * K3[i] + K4[i])
    o = _R_LAM * LANES
    for i in range(4 * LANES):
        Il[i] += Hl[i] / 6.0 * (K1[o + i] + 2.0 * K2[o + i] + 2.0 * K3[o + i] + K4[o + i])


@njit(cache=True, error_model="numpy")
def _lanes_suspect(Yl, Pl, CHM, CNM, K1, nl):
    """Update the running residual maxima from the stage-1 residuals in K1; return the number
    of lanes whose state may carry a stop flag (:func:`_maybe_fatal`: a non-finite entry, a
    d_n outside [0, P_DN_STOP), a residual or a base reach beyond its stop limit)."""
    count = 0
    for l in range(nl):
        CHM[l] = max(CHM[l], max(abs(K1[_R_RES * LANES + l]), abs(K1[(_R_RES + 1) * LANES + l])))
        CNM[l] = max(
            CNM[l], max(abs(K1[(_R_RES + 2) * LANES + l]), abs(K1[(_R_RES + 3) * LANES + l]))
        )
        # as _suspect, on lane l of the structure-of-arrays block
        th_obj = Yl[TH_OBJ * LANES + l]
        bad = _maybe_fatal(
            _state_sum(Yl, l, LANES),
            Yl[DN_1 * LANES + l], Yl[(DN_1 + 1) * LANES + l],
            Yl[TH_1 * LANES + l] - th_obj, Yl[(TH_1 + 1) * LANES + l] + th_obj, CHM[l],
            Pl[P_A * LANES + l], Pl[P_DN_STOP * LANES + l], Pl[P_BASE_STOP * LANES + l],
            Pl[P_CH_STOP * LANES + l],
        )
        count += 1 if bad else 0
    return count


@njit(cache=True)
def _store_lane_impulse(diag, Il, l):
    """:func:`_store_impulse` of lane ``l`` of the block accumulator ``Il`` (4*LANES)."""
    if diag.shape[0] >= N_STEP_DIAG:
        for j in range(4):
            diag[IMPULSE_OFFSET + j] = Il[j * LANES + l]


@njit(cache=True)
def _finish_lanes(Y, U, PRM, Yl, Il, CHM, CNM, ch_limit, DIAG, FLAGS, systems, live, m, n):
    """Write the ``m`` lanes of a block back to their systems: state from ``Yl`` (NY*LANES),
    :func:`_finish` (flags, residuals), substeps ``n`` and the impulses ``Il`` of each live
    lane (``live[l]``; ``systems[l]`` its row in ``Y``, ``DIAG``, ``FLAGS``)."""
    k = np.empty((5, NY))
    work = np.zeros(N_DIAG)
    for l in range(m):
        if live[l]:
            s = systems[l]
            y = Y[s]
            for j in range(NY):
                y[j] = Yl[j * LANES + l]
            FLAGS[s] = _finish(y, U[s], PRM[s], CHM[l], CNM[l], ch_limit, DIAG[s], k, work)
            if DIAG.shape[1] > 2:
                DIAG[s, 2] = n
            _store_lane_impulse(DIAG[s], Il, l)


@njit(cache=True)
def _advance_block(Y, U, PRM, n, ch_limit, DIAG, FLAGS, systems):
    """Advance the systems ``systems`` (at most LANES indices into Y) like :func:`_advance_one`,
    in lanes; spare lanes repeat a live system and are discarded."""
    m = systems.shape[0]
    if m <= _SCALAR_MAX:
        # a nearly empty block is cheaper one system at a time
        k = np.empty((5, NY))
        work = np.zeros(N_DIAG)
        for s in systems:
            FLAGS[s], _ = _advance_one(Y[s], U[s], PRM[s], n, ch_limit, DIAG[s], k, work)
        return
    # lanes computed: a multiple of the vector width, so no scalar remainder runs (a run-time
    # count also keeps LLVM from treating the lane loop as a tiny loop it will not vectorise)
    nl = LANES if m > LANES // 2 else LANES // 2
    Yl = np.empty(NY * LANES)
    Pl = np.empty(_NPU * LANES)
    K1 = np.zeros(_NK * LANES)
    K2 = np.zeros(_NK * LANES)
    K3 = np.zeros(_NK * LANES)
    K4 = np.zeros(_NK * LANES)
    Tl = np.empty(NY * LANES)
    Hl = np.empty(NY * LANES)
    CHM = np.zeros(LANES)
    CNM = np.zeros(LANES)
    Il = np.zeros(4 * LANES)
    live = np.zeros(LANES, dtype=np.bool_)
    for l in range(LANES):
        s = systems[min(l, m - 1)]
        live[l] = l < m
        for j in range(NY):
            Yl[j * LANES + l] = Y[s, j]
        for j in range(N_PARAMS):
            Pl[j * LANES + l] = PRM[s, j]
        Pl[_R_U * LANES + l] = U[s, 0]
        Pl[(_R_U + 1) * LANES + l] = U[s, 1]
        for j in range(NY):
            Hl[j * LANES + l] = PRM[s, P_DT]
    n_live = m
    for step in range(n):
        _rk4_lanes(Yl, Pl, Hl, K1, K2, K3, K4, Tl, Il, nl)
        if _lanes_suspect(Yl, Pl, CHM, CNM, K1, nl) == 0:
            continue
        # some lane may carry a fatal flag: stop those (state, diag and flags of that substep)
        for l in range(m):
            if not live[l]:
                continue
            s = systems[l]
            y = Y[s]
            for j in range(NY):
                y[j] = Yl[j * LANES + l]
            flags = _stop_flags(y, PRM[s], CHM[l], ch_limit)
            if flags != 0:
                FLAGS[s] = flags
                DIAG[s, 0] = CHM[l]
                DIAG[s, 1] = CNM[l]
                if DIAG.shape[1] > 2:
                    DIAG[s, 2] = step + 1
                _store_lane_impulse(DIAG[s], Il, l)
                live[l] = False
                n_live -= 1
        if n_live == 0:
            break
        # stopped and spare lanes follow a live one from here on (finite, never suspect
        # before it is)
        src = 0
        while not live[src]:
            src += 1
        for l in range(nl):
            if not live[l]:
                for j in range(NY):
                    Yl[j * LANES + l] = Yl[j * LANES + src]
                for j in range(_NPU):
                    Pl[j * LANES + l] = Pl[j * LANES + src]
                for j in range(NY):
                    Hl[j * LANES + l] = Hl[j * LANES + src]
                for j in range(4):
                    Il[j * LANES + l] = Il[j * LANES + src]
    if n_live == 0:
        return
    _finish_lanes(Y, U, PRM, Yl, Il, CHM, CNM, ch_limit, DIAG, FLAGS, systems, live, m, n)


@njit(cache=True)
def _plan_blocks(FLAGS):
    """Systems to advance (those without ``FLAG_SKIP`` or a fatal flag) and the block width.

    Returns (active (n_active,) indices, width): blocks of LANES systems; fewer than 4 full
    blocks go in half blocks (less padding, more blocks to share among threads; a full block
    costs ~15% less per system), and up to 2 * _SCALAR_MAX systems one by one (threads share
    them; a lane block would not be faster).
    """
    N = FLAGS.shape[0]
    active = np.empty(N, dtype=np.int64)
    n_active = 0
    for s in range(N):
        if not FLAGS[s] & (FATAL_FLAGS | FLAG_SKIP):
            active[n_active] = s
            n_active += 1
    if n_active >= 4 * LANES:
        width = LANES
    elif n_active > 2 * _SCALAR_MAX:
        width = LANES // 2
    else:
        width = 1
    return active[:n_active], width


@njit(cache=True, parallel=True)
def advance_batch_parallel(Y, U, PRM, n, ch_limit, DIAG, FLAGS):
    """:func:`advance_batch` with the blocks in parallel over numba threads; callable from
    compiled code."""
    active, width = _plan_blocks(FLAGS)
    n_active = active.shape[0]
    n_blocks = (n_active + width - 1) // width
    for b in prange(n_blocks):
        _advance_block(
            Y, U, PRM, n, ch_limit, DIAG, FLAGS,
            active[b * width : min((b + 1) * width, n_active)],
        )


@njit(cache=True)
def advance_batch_serial(Y, U, PRM, n, ch_limit, DIAG, FLAGS):
    """:func:`advance_batch` with the blocks one after the other on the calling thread (what
    it runs for a single system); callable from compiled code."""
    active, width = _plan_blocks(FLAGS)
    n_active = active.shape[0]
    n_blocks = (n_active + width - 1) // width
    for b in range(n_blocks):
        _advance_block(
            Y, U, PRM, n, ch_limit, DIAG, FLAGS,
            active[b * width : min((b + 1) * width, n_active)],
        )


def advance_batch(
    Y: np.ndarray,
    U: np.ndarray,
    PRM: np.ndarray,
    n: int,
    ch_limit: float,
    DIAG: np.ndarray,
    FLAGS: np.ndarray,
    parallel: bool | None = None,
) -> None:
    """Advance ``N`` independent systems ``n`` substeps each, in place, in parallel.

    A single system runs on the calling thread: a parallel region would only add its launch
    and, on a loaded machine, the wait for a descheduled worker thread (milliseconds), for
    nothing to share. ``parallel`` True / False runs the blocks over numba's threads / on the
    calling thread whatever N (the results are the same either way); None (default) is the
    rule above. :class:`~softhand_env.physics.hand.HandPhysics` chooses by measured time
    (:mod:`softhand_env.physics.dispatch`).

    Parameters
    ----------
    Y : ndarray, shape (N, 20), modified in place
    U : ndarray, shape (N, 2)
        Set-points (rad) per system.
    PRM : ndarray, shape (N, N_PARAMS)
        Packed parameters per system (may be a broadcast view of one vector).
    n : int
    ch_limit : float
    DIAG : ndarray, shape (N, 2), (N, 3) or (N, N_STEP_DIAG), output
        max |C^H| (m), max |C^N| (m/s) per system; a third column, if present, receives the
        substeps taken (< n only for a system stopped by a fatal flag); with N_STEP_DIAG = 7
        columns, columns 3-6 also receive the contact impulses J_n1, J_n2, J_t1, J_t2 (N s)
        of the call (module doc).
    FLAGS : ndarray of int64, shape (N,), output
        Status flags per system. On entry, systems carrying ``FLAG_SKIP`` or a fatal flag
        are skipped (their flags are kept); the others get their new flags.
    """
    if parallel is None:
        parallel = Y.shape[0] > 1
    if not parallel:
        advance_batch_serial(Y, U, PRM, n, ch_limit, DIAG, FLAGS)
    else:
        advance_batch_parallel(Y, U, PRM, n, ch_limit, DIAG, FLAGS)


def advance_batch_py(
    Y: np.ndarray, U: np.ndarray, PRM: np.ndarray, n: int, ch_limit: float = CH_LIMIT
) -> tuple[np.ndarray, np.ndarray]:
    """Convenience wrapper of :func:`advance_batch` that allocates the outputs.

    Returns (DIAG (N, N_STEP_DIAG): residuals and contact impulses, FLAGS (N,)).
    """
    N = Y.shape[0]
    DIAG = np.zeros((N, N_STEP_DIAG))
    FLAGS = np.zeros(N, dtype=np.int64)
    PRM = np.ascontiguousarray(np.broadcast_to(PRM, (N, PRM.shape[-1])))
    advance_batch(Y, U, PRM, n, ch_limit, DIAG, FLAGS)
    return DIAG, FLAGS


__all__ = [
    "CH_LIMIT",
    "FATAL_FLAGS",
    "FLAG_BASE",
    "FLAG_CONSTRAINT",
    "FLAG_LOST",
    "FLAG_NONFINITE",
    "FLAG_OVERCOMPRESSED",
    "FLAG_SKIP",
    "IMPULSE_OFFSET",
    "N_STEP_DIAG",
    "advance",
    "advance_batch",
    "advance_batch_parallel",
    "advance_batch_serial",
    "advance_batch_py",
    "base_exceeded",
    "past_base",
]
