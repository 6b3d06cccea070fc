"""Compiled linearly implicit (Rosenbrock) kernels: the CSM model at millisecond steps.

The chapter-5 model is stiff, not fast: Baumgarte's stabilisation puts a double root at
-alpha and a root at -beta (-2e4 and -1e4 /s at Table 5.1) and the finger damping mode (PID
Kd and the fingertip viscosity on the light finger) sits near -8.4e3 /s, while the motion
itself lives below about 700 /s. Classic RK4 must resolve the stiff roots (0.1 ms); the
two-stage Rosenbrock-W method ROS2 (Verwer, Spee, Blom and Hundsdorfer, SIAM J. Sci. Comput.
20, 1999) with gamma = 1 + 1/sqrt(2) is L-stable and of order 2 for *any* matrix W in place of
the Jacobian, so one Jacobian serves a whole call::

    W = I - gamma h J,      W k1 = f(y_n),      W k2 = f(y_n + h k1) - 2 k1,
    y_{n+1} = y_n + 3/2 h k1 + 1/2 h k2.

Jacobian and linear algebra
---------------------------
``J = df/dy`` of :func:`.model.csm_rhs` is taken once per call, at the state the call starts
from, by forward differences of the compiled right-hand side (20 extra evaluations; the
set-points enter f additively through the PID, so J does not depend on them). The rows of
dq/dt = p and dz/dt = theta - theta^d are exact, which reduces ``W k = r`` to a 9 x 9 system
for the momenta (``g = gamma h``)::

    (I - g J_pp - g^2 J_pq - g^3 J_pz S) k_p = r_p + g J_pq r_q + g J_pz (r_z + g S r_q),
    k_q = r_q + g k_p,     k_z = r_z + g S k_q,

(S picks theta_1, theta_2 out of q). The 9 x 9 matrix is LU factorised without pivoting
(its eigenvalues are 1 - g lambda with Re >= 1 for a dissipative linearisation; a zero or
non-finite pivot yields NaN and the state is flagged non-finite) once per step size.

Step schedule
-------------
A call covers ``T = n * prm[P_DT]`` seconds (``n`` counts substeps of the model's ``dt`` as for
RK4, so control periods and grasp phases mean the same under both integrators). Every call may
begin with a set-point jump, whose transient (the finger damping mode, ~0.1 ms) is the part
of the motion a millisecond step resolves worst, so a call starts with a geometric ramp
``H/8, H/8, H/4, H/2`` (together one step H, the integrator's step ``ros2_dt``) and covers the
rest in equal steps of at most H (:func:`step_schedule`). A call shorter than H is the ramp
scaled to T.

Read-outs, failure checks and contact impulses
----------------------------------------------
As in :mod:`.kernel` (same flags, same ``diag`` rows): the residual maxima are taken at the
state each step starts from and at the final state; after every step the state is checked for
a fatal flag and integration stops there (``diag[2]`` then reports the elapsed time in whole
substeps of ``dt``, at least 1). The contact impulses are the integral of the multipliers
with the quadrature ROS2 applies: the integral ``I = int lambda dt`` is integrated as four
extra state components (``dI/dt = lambda(y)``, Jacobian row ``dlambda/dy`` from the same
differences), whose stages are ``kI1 = lambda(y_n) + g L k1`` and
``kI2 = lambda(y_n + h k1) - 2 kI1 + g L k2``, ``I += 3/2 h kI1 + 1/2 h kI2``.

Batches: :func:`advance_batch` integrates blocks of :data:`.kernel.LANES` systems in the
structure-of-arrays lanes of :mod:`.kernel` (the same right-hand side source), in parallel
over blocks. A system integrated alone or in any batch follows the same arithmetic, so it
ends bit for bit equal. All systems of a call must share ``dt`` (one schedule).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from softhand_env.physics.kernel import (
    _NK,
    _NPU,
    _R_LAM,
    _R_U,
    FATAL_FLAGS,
    FLAG_SKIP,
    IMPULSE_OFFSET,
    LANES,
    N_STEP_DIAG,
    _finish,
    _lanes_suspect,
    _rhs_lanes,
    _state_flags,
)
from softhand_env.physics.model import (
    _FASTMATH,
    DN_1,
    DT_1,
    N_DIAG,
    N_PARAMS,
    NQ,
    NY,
    P_ALPHA,
    P_BETA,
    P_CN,
    P_CT,
    P_DT,
    P_I1,
    P_I2,
    P_IOBJ,
    P_KD,
    P_KI,
    P_KP,
    P_MDEF,
    P_MOBJ,
    TH_1,
    TH_OBJ,
    _finger,
    sincos,
)

#: gamma of ROS2 (L-stable choice 1 + 1/sqrt(2)).
GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: Fractions of the step H of the ramp a call starts with (they sum to 1).
RAMP = (0.125, 0.125, 0.25, 0.5)


@njit(cache=True)
def _schedule(T, H):
    """(ramp steps, main steps, main step size) of a call of T seconds with step H."""
    if T <= H * (1.0 + 1e-9):
        return 4, 0, 0.0
    rest = T - H
    k = int(math.ceil(rest / H - 1e-9))
    return 4, k, rest / k


def step_schedule(T: float, H: float) -> np.ndarray:
    """Step sizes (s) a call of ``T`` seconds takes with the integrator step ``H`` (s).

    A ramp ``H/8, H/8, H/4, H/2`` (scaled to T if T <= H), then equal steps of at most H
    covering the rest; the sizes sum to T up to round-off. Returns shape (n_steps,).
    """
    if not (T > 0.0 and H > 0.0):
        raise ValueError(f"T and H must be > 0 (got {T!r}, {H!r})")
    n_ramp, k, h = _schedule(T, H)
    scale = T if k == 0 else H
    return np.array([f * scale for f in RAMP] + [h] * k)


def rhs_evaluations(T: float, H: float) -> int:
    """Right-hand-side evaluations of one call of ``T`` seconds at step ``H``: two per step
    and one at the final state (its residuals), as :func:`.kernel.advance` takes four per
    substep and one at the end."""
    return 2 * len(step_schedule(T, H)) + 1


# rows of the per-lane step matrices (structure of arrays, row r of lane l at [r*LANES + l])
_O_PHI = 0  # Phi (4 x 9): holonomic rows 0-1, rolling rows 2-3
_O_RQ = _O_PHI + 36  # R_q (4 x 9)
_O_RZ = _O_RQ + 36  # R_z (4 x 2)
_O_RP = _O_RZ + 8  # R' = R_p + g R_q + g^2 R_z S (4 x 9)
_O_MI = _O_RP + 36  # M^-1 (9)
_O_DI = _O_MI + 9  # Delta^-1 (9)
_O_NLU = _O_DI + 9  # LU of N (4 x 4), inverse pivots on the diagonal
_O_MK = _O_NLU + 16  # M^-1 Kp on theta_1, theta_2 (2)
_O_MZ = _O_MK + 2  # M^-1 Ki on theta_1, theta_2 (2)
_O_CH = _O_MZ + 2  # C^H (2) at the state of _phi_lanes
_NW = _O_CH + 2


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _phi_lanes(Yl, Pl, Wl, nl):
    """Constraint Jacobian Phi (4 x 9, :func:`.model.constraint_terms`) of lanes 0..nl-1 into
    rows _O_PHI.. of Wl, and M^-1 into rows _O_MI.."""
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
        so, co = sincos(y[TH_OBJ])
        s1, A1, B1, E1, F1, _, _, CH1 = _finger(y, prm, 0, co, so)[:8]
        s2, A2, B2, E2, F2, _, _, CH2 = _finger(y, prm, 1, co, so)[:8]
        Wl[_O_CH * LANES + l] = CH1
        Wl[(_O_CH + 1) * LANES + l] = CH2
        o = _O_PHI * LANES + l
        for j in range(36):
            Wl[o + j * LANES] = 0.0
        # row r, column j at o + (9 r + j) LANES
        Wl[o + 0 * LANES] = s1 * co
        Wl[o + 1 * LANES] = s1 * so
        Wl[o + 2 * LANES] = A1
        Wl[o + (TH_1) * LANES] = B1
        Wl[o + (DN_1) * LANES] = 1.0
        Wl[o + 9 * LANES] = s2 * co
        Wl[o + 10 * LANES] = s2 * so
        Wl[o + 11 * LANES] = A2
        Wl[o + (9 + TH_1 + 1) * LANES] = B2
        Wl[o + (9 + DN_1 + 1) * LANES] = 1.0
        Wl[o + 18 * LANES] = -so
        Wl[o + 19 * LANES] = co
        Wl[o + 20 * LANES] = E1
        Wl[o + (18 + TH_1) * LANES] = F1
        Wl[o + (18 + DT_1) * LANES] = 1.0
        Wl[o + 27 * LANES] = -so
        Wl[o + 28 * LANES] = co
        Wl[o + 29 * LANES] = E2
        Wl[o + (27 + TH_1 + 1) * LANES] = F2
        Wl[o + (27 + DT_1 + 1) * LANES] = 1.0
        mi = _O_MI * LANES + l
        Wl[mi + 0 * LANES] = 1.0 / prm[P_MOBJ]
        Wl[mi + 1 * LANES] = 1.0 / prm[P_MOBJ]
        Wl[mi + 2 * LANES] = 1.0 / prm[P_IOBJ]
        Wl[mi + 3 * LANES] = 1.0 / prm[P_I1]
        Wl[mi + 4 * LANES] = 1.0 / prm[P_I2]
        for j in range(5, NQ):
            Wl[mi + j * LANES] = 1.0 / prm[P_MDEF]


@njit(cache=True, error_model="numpy")
def _setup_lanes(Yl, Pl, g, Wl, S, nl):
    """The step matrices of W = I - g J_W for g = gamma h at the states Yl (rows of Wl, see
    the module doc); S (16*LANES) scratch for Phi M^-1 Phi^T."""
    _phi_lanes(Yl, Pl, Wl, nl)
    L = LANES
    for l in range(nl):
        Wl[(_O_MK + 0) * L + l] = Wl[(_O_MI + TH_1) * L + l] * Pl[P_KP * L + l]
        Wl[(_O_MK + 1) * L + l] = Wl[(_O_MI + TH_1 + 1) * L + l] * Pl[P_KP * L + l]
        Wl[(_O_MZ + 0) * L + l] = Wl[(_O_MI + TH_1) * L + l] * Pl[P_KI * L + l]
        Wl[(_O_MZ + 1) * L + l] = Wl[(_O_MI + TH_1 + 1) * L + l] * Pl[P_KI * L + l]
    # Delta = 1 + g M^-1 D + g^2 M^-1 Kp + g^3 M^-1 Ki (the last two on the finger angles)
    for j in range(NQ):
        for l in range(nl):
            mi = Wl[(_O_MI + j) * L + l]
            if j == TH_1 or j == TH_1 + 1:
                d = Pl[P_KD * L + l]
            elif j == DN_1 or j == DN_1 + 1:
                d = Pl[P_CN * L + l]
            elif j == DT_1 or j == DT_1 + 1:
                d = Pl[P_CT * L + l]
            else:
                d = 0.0
            delta = 1.0 + g * mi * d
            if j == TH_1 or j == TH_1 + 1:
                i = j - TH_1
                delta += g * g * Wl[(_O_MK + i) * L + l] + g * g * g * Wl[(_O_MZ + i) * L + l]
            Wl[(_O_DI + j) * L + l] = 1.0 / delta
    # R_q = Phi M^-1 K - [alpha^2 Phi^H; 0], R_z = Phi M^-1 Ki S^T,
    # R' = (Phi M^-1 D - [2 alpha Phi^H; beta Phi^N]) + g R_q + g^2 R_z S
    for r in range(4):
        for j in range(NQ):
            ph = (_O_PHI + NQ * r + j) * L
            for l in range(nl):
                phi = Wl[ph + l]
                mi = Wl[(_O_MI + j) * L + l]
                alpha = Pl[P_ALPHA * L + l]
                if j == TH_1 or j == TH_1 + 1:
                    d = Pl[P_KD * L + l]
                    kq = Wl[(_O_MK + j - TH_1) * L + l]
                elif j == DN_1 or j == DN_1 + 1:
                    d = Pl[P_CN * L + l]
                    kq = 0.0
                elif j == DT_1 or j == DT_1 + 1:
                    d = Pl[P_CT * L + l]
                    kq = 0.0
                else:
                    d = 0.0
                    kq = 0.0
                if r < 2:
                    rp = phi * (mi * d - 2.0 * alpha)
                    rq = phi * (kq - alpha * alpha)
                else:
                    rp = phi * (mi * d - Pl[P_BETA * L + l])
                    rq = phi * kq
                Wl[(_O_RQ + NQ * r + j) * L + l] = rq
                Wl[(_O_RP + NQ * r + j) * L + l] = rp + g * rq
        for i in range(2):
            for l in range(nl):
                rz = Wl[(_O_PHI + NQ * r + TH_1 + i) * L + l] * Wl[(_O_MZ + i) * L + l]
                Wl[(_O_RZ + 2 * r + i) * L + l] = rz
                Wl[(_O_RP + NQ * r + TH_1 + i) * L + l] += g * g * rz
    # N = Phi M^-1 Phi^T - g R' Delta^-1 M^-1 Phi^T, factorised without pivoting
    for a in range(4):
        for b in range(4):
            for l in range(nl):
                S[(4 * a + b) * L + l] = 0.0
            for j in range(NQ):
                pa = (_O_PHI + NQ * a + j) * L
                pb = (_O_PHI + NQ * b + j) * L
                ra = (_O_RP + NQ * a + j) * L
                mj = (_O_MI + j) * L
                dj = (_O_DI + j) * L
                for l in range(nl):
                    S[(4 * a + b) * L + l] += (
                        (Wl[pa + l] - g * Wl[ra + l] * Wl[dj + l]) * Wl[mj + l] * Wl[pb + l]
                    )
    for k in range(4):
        dk = (4 * k + k) * L
        for l in range(nl):
            piv = S[dk + l]
            S[dk + l] = 1.0 / piv if piv != 0.0 else math.nan
        for r in range(k + 1, 4):
            dr = (4 * r + k) * L
            for l in range(nl):
                S[dr + l] *= S[dk + l]
            for c in range(k + 1, 4):
                drc = (4 * r + c) * L
                dkc = (4 * k + c) * L
                for l in range(nl):
                    S[drc + l] -= S[dr + l] * S[dkc + l]
    for i in range(16 * L):
        Wl[_O_NLU * L + i] = S[i]


@njit(cache=True, error_model="numpy")
def _solve_lanes(R, Wl, g, Kout, MU, C, nl):
    """Solve W k = R (NY*LANES rows) per lane; Kout (NY*LANES) receives k, MU (4*LANES) the
    multiplier stage L_W k; C (NQ*LANES) scratch."""
    L = LANES
    # c = r_p - g M^-1 Kp r_q - g M^-1 Ki (r_z + g r_q) on the finger angles
    for j in range(NQ):
        for l in range(nl):
            C[j * L + l] = R[(NQ + j) * L + l]
    for i in range(2):
        t = TH_1 + i
        for l in range(nl):
            rq = R[t * L + l]
            C[t * L + l] -= g * Wl[(_O_MK + i) * L + l] * rq + g * Wl[(_O_MZ + i) * L + l] * (
                R[(2 * NQ + i) * L + l] + g * rq
            )
    # N mu = R' Delta^-1 c + R_q r_q + R_z (r_z + g S r_q)
    for a in range(4):
        for l in range(nl):
            MU[a * L + l] = 0.0
        for j in range(NQ):
            ra = (_O_RP + NQ * a + j) * L
            qa = (_O_RQ + NQ * a + j) * L
            dj = (_O_DI + j) * L
            for l in range(nl):
                MU[a * L + l] += Wl[ra + l] * Wl[dj + l] * C[j * L + l] + Wl[qa + l] * R[j * L + l]
        for i in range(2):
            za = (_O_RZ + 2 * a + i) * L
            for l in range(nl):
                MU[a * L + l] += Wl[za + l] * (R[(2 * NQ + i) * L + l] + g * R[(TH_1 + i) * L + l])
    o = _O_NLU * L
    for r in range(1, 4):
        for c in range(r):
            for l in range(nl):
                MU[r * L + l] -= Wl[o + (4 * r + c) * L + l] * MU[c * L + l]
    for r in range(3, -1, -1):
        for c in range(r + 1, 4):
            for l in range(nl):
                MU[r * L + l] -= Wl[o + (4 * r + c) * L + l] * MU[c * L + l]
        for l in range(nl):
            MU[r * L + l] *= Wl[o + (4 * r + r) * L + l]
    # k_p = Delta^-1 (c + g M^-1 Phi^T mu), k_q = r_q + g k_p, k_z = r_z + g S k_q
    for j in range(NQ):
        for l in range(nl):
            s = 0.0
            for a in range(4):
                s += Wl[(_O_PHI + NQ * a + j) * L + l] * MU[a * L + l]
            kp = Wl[(_O_DI + j) * L + l] * (C[j * L + l] + g * Wl[(_O_MI + j) * L + l] * s)
            Kout[(NQ + j) * L + l] = kp
            Kout[j * L + l] = R[j * L + l] + g * kp
    for i in range(2):
        for l in range(nl):
            Kout[(2 * NQ + i) * L + l] = R[(2 * NQ + i) * L + l] + g * Kout[(TH_1 + i) * L + l]


@njit(cache=True, error_model="numpy")
def _ros2_lanes(Yl, Pl, h, Wl, S, K1, K2, F1, F2, Tl, C, I1, I2, Il, nl):
    """One ROS2 step of every lane in place; F1 (_NK*LANES) must hold f(Yl) on entry (the
    stage-1 evaluation, also the source of the step's residuals); adds the step's impulses to
    Il (4*LANES)."""
    g = GAMMA * h
    L = LANES
    _setup_lanes(Yl, Pl, g, Wl, S, nl)
    _solve_lanes(F1, Wl, g, K1, I1, C, nl)
    # multiplier-integral stage 1: lambda(y_n) + g L_W k1
    for r in range(4):
        for l in range(nl):
            I1[r * L + l] = F1[(_R_LAM + r) * L + l] + g * I1[r * L + l]
    for i in range(NY * L):
        Tl[i] = Yl[i] + h * K1[i]
    _rhs_lanes(Tl, Pl, F2, nl)
    for i in range(NY * L):
        F2[i] = F2[i] - 2.0 * K1[i]
    _solve_lanes(F2, Wl, g, K2, I2, C, nl)
    for r in range(4):
        for l in range(nl):
            I2[r * L + l] = F2[(_R_LAM + r) * L + l] - 2.0 * I1[r * L + l] + g * I2[r * L + l]
    for i in range(NY * L):
        Yl[i] += 1.5 * h * K1[i] + 0.5 * h * K2[i]
    for i in range(4 * L):
        Il[i] += 1.5 * h * I1[i] + 0.5 * h * I2[i]


@njit(cache=True, error_model="numpy")
def _gram(Wl, l, S):
    """S (4, 4) = Phi M^-1 Phi^T of lane ``l`` from the rows of Wl (after _phi_lanes)."""
    L = LANES
    ph = _O_PHI * L + l
    mi = _O_MI * L + l
    for a in range(4):
        for b in range(a + 1):
            acc = 0.0
            for j in range(NQ):
                acc += Wl[ph + (NQ * a + j) * L] * Wl[mi + j * L] * Wl[ph + (NQ * b + j) * L]
            S[a, b] = acc
            S[b, a] = acc


@njit(cache=True, error_model="numpy")
def _spd_solve(S, v, out):
    """out = S^-1 v for a symmetric positive definite (4, 4) S (Gaussian elimination without
    pivoting; S and v are overwritten)."""
    for k in range(4):
        for r in range(k + 1, 4):
            f = S[r, k] / S[k, k]
            for c in range(k + 1, 4):
                S[r, c] -= f * S[k, c]
            v[r] -= f * v[k]
    for r in range(3, -1, -1):
        acc = v[r]
        for c in range(r + 1, 4):
            acc -= S[r, c] * out[c]
        out[r] = acc / S[r, r]


@njit(cache=True, error_model="numpy")
def _project_lanes(Yl, Pl, Wl, Il, nl):
    """Project the states of lanes 0..nl-1 onto the constraint manifold, in place.

    Positions: one Newton step on C^H(q) = 0 along displacements that do not roll the
    contacts (Phi^N dq = 0: the rolling history is kept), the M-weighted shortest one,
    ``dq = M^-1 Phi^T nu``, ``(Phi M^-1 Phi^T) nu = [-C^H; 0]``. Momenta (with Phi at the new
    q): onto Phi p = 0 (C^H-dot = 0, C^N = 0), ``dp = M^-1 Phi^T mu``,
    ``mu = -(Phi M^-1 Phi^T)^-1 Phi p``, whose contact impulse mu (N s) is added to Il."""
    L = LANES
    S = np.empty((4, 4))
    v = np.empty(4)
    mu = np.empty(4)
    _phi_lanes(Yl, Pl, Wl, nl)
    for l in range(nl):
        ph = _O_PHI * L + l
        mi = _O_MI * L + l
        _gram(Wl, l, S)
        v[0] = -Wl[_O_CH * L + l]
        v[1] = -Wl[(_O_CH + 1) * L + l]
        v[2] = 0.0
        v[3] = 0.0
        _spd_solve(S, v, mu)
        for j in range(NQ):
            acc = 0.0
            for a in range(4):
                acc += Wl[ph + (NQ * a + j) * L] * mu[a]
            Yl[j * L + l] += Wl[mi + j * L] * acc
    _phi_lanes(Yl, Pl, Wl, nl)
    for l in range(nl):
        ph = _O_PHI * L + l
        mi = _O_MI * L + l
        _gram(Wl, l, S)
        for a in range(4):
            acc = 0.0
            for j in range(NQ):
                acc += Wl[ph + (NQ * a + j) * L] * Yl[(NQ + j) * L + l]
            v[a] = -acc
        _spd_solve(S, v, mu)
        for a in range(4):
            Il[a * L + l] += mu[a]
        for j in range(NQ):
            acc = 0.0
            for a in range(4):
                acc += Wl[ph + (NQ * a + j) * L] * mu[a]
            Yl[(NQ + j) * L + l] += Wl[mi + j * L] * acc


@njit(cache=True)
def _advance_block(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS, systems):
    """Advance the systems ``systems`` (at most LANES indices into Y) one call, in lanes;
    spare lanes repeat a live system and are discarded."""
    m = systems.shape[0]
    nl = m if m <= 2 else (LANES if m > LANES // 2 else LANES // 2)
    Yl = np.empty(NY * LANES)
    Pl = np.empty(_NPU * LANES)
    Wl = np.zeros(_NW * LANES)
    S = np.zeros(16 * LANES)
    K1 = np.zeros(NY * LANES)
    K2 = np.zeros(NY * LANES)
    F1 = np.zeros(_NK * LANES)
    F2 = np.zeros(_NK * LANES)
    Tl = np.empty(NY * LANES)
    C = np.zeros(NQ * LANES)
    I1 = np.zeros(4 * LANES)
    I2 = np.zeros(4 * LANES)
    Il = np.zeros(4 * LANES)
    CHM = np.zeros(LANES)
    CNM = np.zeros(LANES)
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
    dt = PRM[systems[0], P_DT]
    T = n * dt
    n_ramp, k_main, h_main = _schedule(T, H)
    scale = T if k_main == 0 else H
    n_live = m
    t = 0.0
    for step in range(n_ramp + k_main):
        h = RAMP[step] * scale if step < n_ramp else h_main
        _rhs_lanes(Yl, Pl, F1, nl)
        _ros2_lanes(Yl, Pl, h, Wl, S, K1, K2, F1, F2, Tl, C, I1, I2, Il, nl)
        _project_lanes(Yl, Pl, Wl, Il, nl)
        t += h
        if _lanes_suspect(Yl, Pl, CHM, CNM, F1, nl) == 0:
            continue
        done = min(n, max(1, int(round(t / dt))))
        for l in range(m):
            if not live[l]:
                continue
            s = systems[l]
            y = Y[s]
            for j in range(NY):
                y[j] = Yl[j * LANES + l]
            flags = _state_flags(y, PRM[s], 0.0, ch_limit)
            if flags != 0:
                FLAGS[s] = flags
                DIAG[s, 0] = CHM[l]
                DIAG[s, 1] = CNM[l]
                if DIAG.shape[1] > 2:
                    DIAG[s, 2] = done
                _store_lane_impulse(DIAG[s], Il, l)
                live[l] = False
                n_live -= 1
        if n_live == 0:
            break
        src = 0
        while not live[src]:
            src += 1
        for l in range(nl):
            if not live[l]:
                _copy_lane(Yl, NY, src, l)
                _copy_lane(Pl, _NPU, src, l)
                _copy_lane(Il, 4, src, l)
    if n_live == 0:
        return
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


@njit(cache=True, inline="always")
def _copy_lane(A, rows, src, dst):
    """Copy lane ``src`` of the structure-of-arrays block A (rows*LANES) into lane ``dst``."""
    for j in range(rows):
        A[j * LANES + dst] = A[j * LANES + src]


@njit(cache=True)
def _store_lane_impulse(diag, Il, l):
    """Impulses of lane ``l`` (Il, 4*LANES) into entries 3-6 of ``diag`` if it has room."""
    if diag.shape[0] >= N_STEP_DIAG:
        for j in range(4):
            diag[IMPULSE_OFFSET + j] = Il[j * LANES + l]


@njit(cache=True)
def _plan_blocks(FLAGS):
    """Systems to advance and the block width (as :func:`.kernel._plan_blocks`, but a
    lane block also for few systems: the Jacobian and the solves vectorise)."""
    N = FLAGS.shape[0]
    active = np.empty(N, dtype=np.int64)
    n_active = 0
    for s in range(N):
        if not FLAGS[s] & (FATAL_FLAGS | FLAG_SKIP):
            active[n_active] = s
            n_active += 1
    if n_active >= 4 * LANES:
        width = LANES
    elif n_active > 2:
        width = LANES // 2
    else:
        width = 1
    return active[:n_active], width


@njit(cache=True, parallel=True)
def _advance_parallel(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS):
    active, width = _plan_blocks(FLAGS)
    n_active = active.shape[0]
    n_blocks = (n_active + width - 1) // width
    for b in prange(n_blocks):
        _advance_block(
            Y, U, PRM, n, H, ch_limit, DIAG, FLAGS,
            active[b * width : min((b + 1) * width, n_active)],
        )


@njit(cache=True)
def advance_batch_serial(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS):
    """:func:`advance_batch` with the blocks one after the other on the calling thread;
    callable from compiled code."""
    active, width = _plan_blocks(FLAGS)
    n_active = active.shape[0]
    n_blocks = (n_active + width - 1) // width
    for b in range(n_blocks):
        _advance_block(
            Y, U, PRM, n, H, ch_limit, DIAG, FLAGS,
            active[b * width : min((b + 1) * width, n_active)],
        )


def _check_uniform_dt(PRM: np.ndarray) -> None:
    if PRM.shape[0] > 1 and not np.all(PRM[:, P_DT] == PRM[0, P_DT]):
        raise ValueError("every system of a ROS2 call must have the same dt (one schedule)")


def advance_batch(
    Y: np.ndarray,
    U: np.ndarray,
    PRM: np.ndarray,
    n: int,
    H: float,
    ch_limit: float,
    DIAG: np.ndarray,
    FLAGS: np.ndarray,
) -> None:
    """Advance ``N`` systems over ``n`` substeps of their ``dt`` with ROS2 at step ``H``.

    Arguments and outputs as :func:`softhand_env.physics.kernel.advance_batch`, plus

    H : float
        The ROS2 step (s) (the steps of :func:`step_schedule`).

    ``DIAG[:, 2]`` receives ``n`` for a completed call, else the elapsed time in whole
    substeps of ``dt`` at the fatal stop. Every system must have the same ``dt``
    (``ValueError`` otherwise).
    """
    if not H > 0.0:
        raise ValueError(f"H must be > 0 (got {H!r})")
    _check_uniform_dt(PRM)
    if Y.shape[0] == 1:
        advance_batch_serial(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS)
    else:
        _advance_parallel(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS)


def advance(
    y: np.ndarray, u: np.ndarray, prm: np.ndarray, n: int, H: float, ch_limit: float,
    diag: np.ndarray,
) -> tuple[int, int]:
    """Advance one system (as :func:`softhand_env.physics.kernel.advance`) with ROS2 at step
    ``H`` (s); ``y`` (20,) in place, ``diag`` (2,), (3,) or (N_STEP_DIAG,). Returns (flags,
    substeps of dt elapsed)."""
    Y = y.reshape(1, NY)
    D = np.zeros((1, max(3, diag.shape[0])))
    F = np.zeros(1, dtype=np.int64)
    advance_batch_serial(Y, u.reshape(1, 2), prm.reshape(1, -1), n, H, ch_limit, D, F)
    diag[:] = D[0, : diag.shape[0]]
    return int(F[0]), int(D[0, 2])


__all__ = [
    "GAMMA",
    "RAMP",
    "advance",
    "advance_batch",
    "advance_batch_serial",
    "rhs_evaluations",
    "ros2_step",
    "step_schedule",
]


@njit(cache=True)
def ros2_step(y, u, prm, h):
    """One ROS2 step of ``h`` seconds of one system, in place (``y`` (20,), ``u`` (2,), ``prm``
    (N_PARAMS,)): the step of the kernels, for analysis (e.g. the linearised step map of
    :mod:`softhand_env.physics.stability`). No checks, no impulses."""
    Yl = np.zeros(NY * LANES)
    Pl = np.zeros(_NPU * LANES)
    for j in range(NY):
        Yl[j * LANES] = y[j]
    for j in range(N_PARAMS):
        Pl[j * LANES] = prm[j]
    Pl[_R_U * LANES] = u[0]
    Pl[(_R_U + 1) * LANES] = u[1]
    Wl = np.zeros(_NW * LANES)
    S = np.zeros(16 * LANES)
    K1 = np.zeros(NY * LANES)
    K2 = np.zeros(NY * LANES)
    F1 = np.zeros(_NK * LANES)
    F2 = np.zeros(_NK * LANES)
    Tl = np.zeros(NY * LANES)
    C = np.zeros(NQ * LANES)
    I1 = np.zeros(4 * LANES)
    I2 = np.zeros(4 * LANES)
    Il = np.zeros(4 * LANES)
    _rhs_lanes(Yl, Pl, F1, 1)
    _ros2_lanes(Yl, Pl, h, Wl, S, K1, K2, F1, F2, Tl, C, I1, I2, Il, 1)
    _project_lanes(Yl, Pl, Wl, Il, 1)
    for j in range(NY):
        y[j] = Yl[j * LANES]
