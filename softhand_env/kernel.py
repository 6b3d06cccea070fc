"""Compiled RK4 kernels that advance the CSM model many 0.1 ms substeps per call.

* :func:`advance` integrates one system ``n`` classic-RK4 substeps with constant set-points,
  tracks the largest constraint residuals seen and stops at the first invalid state.
* :func:`advance_batch` does the same for ``N`` independent systems in parallel (numba
  ``prange``); each system may have its own parameter vector.

Status flags (bitwise OR, returned per system):

=====================  =====  ==========================================================
flag                   value  meaning
=====================  =====  ==========================================================
``FLAG_NONFINITE``     1      NaN or inf in the state (fatal)
``FLAG_CONSTRAINT``    2      max |C^H| above ``ch_limit`` (fatal, default 1e-3 m)
``FLAG_LOST``          4      a normal deformation d_n < 0: the grasp is lost (fatal: the
                              bilateral constraint would pull the object)
``FLAG_OVERCOMPRESSED`` 8     a normal deformation d_n >= a (fatal: outside the model)
``FLAG_BASE``          16     the contact circle passed the fingertip base,
                              tan(theta_p) > (a - d_n)/a_c, where the closed-form energy
                              over-predicts (not fatal; checked at the end of the call)
``FLAG_SKIP``          32     input only: :func:`advance_batch` leaves this system alone
                              (e.g. an environment that restarts this step)
=====================  =====  ==========================================================

Integration stops at the substep where a fatal flag is raised, leaving the state at that
substep; the number of substeps actually taken is returned.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from softhand_env.model import DN_1, N_DIAG, NY, P_A, P_DT, TH_1, TH_OBJ, csm_rhs

FLAG_NONFINITE = 1
FLAG_CONSTRAINT = 2
FLAG_LOST = 4
FLAG_OVERCOMPRESSED = 8
FLAG_BASE = 16
FLAG_SKIP = 32
FATAL_FLAGS = FLAG_NONFINITE | FLAG_CONSTRAINT | FLAG_LOST | FLAG_OVERCOMPRESSED
#: Default bound on |C^H| (m) above which the state counts as diverged.
CH_LIMIT = 1e-3


@njit(cache=True)
def _rk4_substep(y, u, prm, h, k, work):
    """One classic RK4 step of :func:`csm_rhs` in place; ``k`` is (5, NY) scratch, ``work`` the
    (N_DIAG,) diagnostics of the stage-1 evaluation.

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
    for j in range(NY):
        tmp[j] = y[j] + 0.5 * h * k1[j]
    csm_rhs(tmp, u, prm, k2, work)
    for j in range(NY):
        tmp[j] = y[j] + 0.5 * h * k2[j]
    csm_rhs(tmp, u, prm, k3, work)
    for j in range(NY):
        tmp[j] = y[j] + h * k3[j]
    csm_rhs(tmp, u, prm, k4, work)
    for j in range(NY):
        y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    return ch, cn


@njit(cache=True)
def _state_flags(y, prm, ch, ch_limit):
    """Fatal flags of state y given its holonomic residual ch."""
    flags = 0
    for j in range(NY):
        if not math.isfinite(y[j]):
            return FLAG_NONFINITE
    if ch > ch_limit:
        flags |= FLAG_CONSTRAINT
    a = prm[P_A]
    for i in range(2):
        dn = y[DN_1 + i]
        if dn < 0.0:
            flags |= FLAG_LOST
        elif dn >= a:
            flags |= FLAG_OVERCOMPRESSED
    return flags


@njit(cache=True)
def base_exceeded(y, prm):
    """True if a contact circle has passed its fingertip base (tan theta_p > (a-d)/a_c)."""
    a = prm[P_A]
    for i in range(2):
        dn = y[DN_1 + i]
        if dn <= 0.0 or dn >= a:
            continue
        sgn = -1.0 if i == 0 else 1.0
        tp = math.tan(y[TH_1 + i] + sgn * y[TH_OBJ])
        ac = math.sqrt(a * a - (a - dn) ** 2)
        if abs(tp) * ac > (a - dn):
            return True
    return False


@njit(cache=True)
def _advance_one(y, u, prm, n, ch_limit, diag, k, work):
    h = prm[P_DT]
    ch_max = 0.0
    cn_max = 0.0
    flags = 0
    done = 0
    for _ in range(n):
        ch, cn = _rk4_substep(y, u, prm, h, k, work)
        ch_max = max(ch_max, ch)
        cn_max = max(cn_max, cn)
        done += 1
        flags = _state_flags(y, prm, 0.0, ch_limit)
        if flags != 0:
            break
    if flags == 0:
        # residuals of the final state (the next stage-1 evaluation)
        csm_rhs(y, u, prm, k[0], work)
        ch_max = max(ch_max, abs(work[0]), abs(work[1]))
        cn_max = max(cn_max, abs(work[2]), abs(work[3]))
        flags = _state_flags(y, prm, ch_max, ch_limit)
        if flags == 0 and base_exceeded(y, prm):
            flags = FLAG_BASE
    diag[0] = ch_max
    diag[1] = cn_max
    return flags, done


@njit(cache=True)
def advance(y, u, prm, n, ch_limit, diag):
    """Advance one system ``n`` RK4 substeps of ``prm[P_DT]`` seconds, in place.

    Parameters
    ----------
    y : ndarray, shape (20,), float64, modified in place
        State [q, p, z] (see :mod:`softhand_env.model`).
    u : ndarray, shape (2,)
        Finger-angle set-points (rad), held constant over the call.
    prm : ndarray, shape (N_PARAMS,)
        Packed parameters (:func:`softhand_env.model.pack_params`).
    n : int
        Number of substeps.
    ch_limit : float
        |C^H| (m) above which the state is flagged as diverged.
    diag : ndarray, shape (2,), output
        max |C^H| (m) and max |C^N| (m/s) over the states visited.

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


@njit(cache=True, parallel=True)
def advance_batch(Y, U, PRM, n, ch_limit, DIAG, FLAGS):
    """Advance ``N`` independent systems ``n`` substeps each, in place, in parallel.

    Parameters
    ----------
    Y : ndarray, shape (N, 20), modified in place
    U : ndarray, shape (N, 2)
        Set-points (rad) per system.
    PRM : ndarray, shape (N, N_PARAMS)
        Packed parameters per system (may be a broadcast view of one vector).
    n : int
    ch_limit : float
    DIAG : ndarray, shape (N, 2), output
        max |C^H| (m), max |C^N| (m/s) per system.
    FLAGS : ndarray of int64, shape (N,), output
        Status flags per system. On entry, systems carrying ``FLAG_SKIP`` or a fatal flag
        are skipped (their flags are kept); the others get their new flags.
    """
    N = Y.shape[0]
    for s in prange(N):
        if FLAGS[s] & (FATAL_FLAGS | FLAG_SKIP):
            continue
        k = np.empty((5, NY))
        work = np.zeros(N_DIAG)
        flags, _ = _advance_one(Y[s], U[s], PRM[s], n, ch_limit, DIAG[s], k, work)
        FLAGS[s] = flags


def advance_batch_py(
    Y: np.ndarray, U: np.ndarray, PRM: np.ndarray, n: int, ch_limit: float = CH_LIMIT
) -> tuple[np.ndarray, np.ndarray]:
    """Convenience wrapper of :func:`advance_batch` that allocates the outputs.

    Returns (DIAG (N, 2), FLAGS (N,)).
    """
    N = Y.shape[0]
    DIAG = np.zeros((N, 2))
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
    "advance",
    "advance_batch",
    "advance_batch_py",
    "base_exceeded",
]
