"""Compiled linearly implicit (Rosenbrock) kernels: the CSM model at millisecond steps.

The chapter-5 model is stiff, not fast: Baumgarte's stabilisation puts a double root at
-alpha and a root at -beta (-2e4 and -1e4 /s at Table 5.1) and the finger damping mode (PID
Kd and the fingertip viscosity on the light finger) sits near -8.4e3 /s, while the motion
itself lives below about 700 /s. Classic RK4 must resolve the stiff roots (0.1 ms); the
two-stage Rosenbrock-W method ROS2 (Verwer, Spee, Blom and Hundsdorfer, SIAM J. Sci. Comput.
20, 1999) with gamma = 1 + 1/sqrt(2) is L-stable and of order 2 for *any* matrix J_W in place
of the Jacobian, so J_W may be its stiff part alone::

    W = I - gamma h J_W,    W k1 = f(y_n),      W k2 = f(y_n + h k1) - 2 k1,
    y_{n+1} = y_n + 3/2 h k1 + 1/2 h k2.

The matrix W and its solve
--------------------------
``J_W`` is the stiff part of the Jacobian of :func:`.model.csm_rhs`, analytic and rebuilt every
step from the constraint Jacobian Phi at y_n (a Jacobian reused over a control step is not good
enough: after a set-point jump the state moves too far within one). With
``lambda = S^-1 (-gamma - Phi M^-1 f)`` and S = Phi M^-1 Phi^T, its momentum rows are
``dp'/dy = -diag + M^-1 Phi^T dlambda/dy`` with

    dlambda/dp = S^-1 (Phi M^-1 D - [2 alpha Phi^H; beta Phi^N]),
    dlambda/dq = S^-1 (Phi M^-1 K - [alpha^2 Phi^H; 0]),   dlambda/dz = S^-1 Phi M^-1 Ki S^T

(D: Kd on theta_i, c_n on d_n, c_t on d_t; K: Kp on theta_i; S^T maps z_i to theta_i); the
rows of dq/dt = p and dz/dt = theta - theta^d are exact. The elastic stiffness and the
geometric terms (dPhi/dq times the multipliers) are left out; the W-method stays of order 2,
and :mod:`softhand_env.physics.stability` checks the stability of the step as implemented. With
``g = gamma h``, ``e = M^-1 (D + g K + g^2 Ki)`` and ``Delta = 1 + g e`` (diagonal), eliminating
k_q = r_q + g k_p and k_z = r_z + g S k_q leaves for the momenta a diagonal system plus a rank-4
term, solved through the 4 x 4 multiplier stage mu = dlambda/dy k::

    diag(1 + g kappa) G mu = sum_j Phi_j [(e_j - kappa) Delta_j^-1 c_j + (k_j - c2) r_q,j] + ...,
    G = Phi diag(M^-1 Delta^-1) Phi^T,   k_p = Delta^-1 (c + g M^-1 Phi^T mu)

(kappa = 2 alpha + g alpha^2 on the holonomic rows, beta on the rolling ones; c is r_p with
the PID terms of r_q, r_z; see :func:`_solve_lanes`). G is symmetric positive definite and
factorised as L D L^T; a pivot <= 0 gives NaN and the state is flagged non-finite.

Projection
----------
After every step the state is put back on the constraint manifold (:func:`_project_lanes`):
one Newton step on C^H = 0 along displacements that keep the rolling history (Phi^N dq = 0),
then the momenta onto Phi p = 0. The residual maxima are therefore round-off; the momentum the
projection removes is a contact impulse and is added to the step's impulses.

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
state each step starts from (after the previous step's projection) and at the final state;
after every step the state is checked for a fatal flag and integration stops there
(``diag[2]`` then reports the elapsed time in whole substeps of ``dt``, at least 1). The
contact impulses are the integral of the multipliers with the quadrature ROS2 applies (plus
the projection's impulse): the integral ``I = int lambda dt`` is integrated as four
extra state components (``dI/dt = lambda(y)``, with the rows dlambda/dy of J_W above), whose
stages are ``kI1 = lambda(y_n) + g L k1`` and
``kI2 = lambda(y_n + h k1) - 2 kI1 + g L k2``, ``I += 3/2 h kI1 + 1/2 h kI2``.

Batches: :func:`advance_batch` integrates blocks of :data:`.kernel.LANES` systems in the
structure-of-arrays lanes of :mod:`.kernel` (the same right-hand side source, vectorised; the
step data, solves and projection run lane by lane in scalar code), in parallel over blocks.
A system integrated alone or in any batch follows the same arithmetic, so it ends bit for
bit equal. All systems of a call must share ``dt`` (one schedule).
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
    LANES,
    _finish_lanes,
    _lanes_suspect,
    _rhs_lanes,
    _state_flags,
    _store_lane_impulse,
)
from softhand_env.physics.model import (
    _FASTMATH,
    DN_1,
    DT_1,
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


# per-lane step data W[l, :] (one row per lane of a block)
_W_PHI = 0  # Phi (4 x 9, row-major): holonomic rows 0-1, rolling rows 2-3
_W_MI = 36  # M^-1 (9)
_W_E = 45  # e = M^-1 D + g M^-1 Kp + g^2 M^-1 Ki (the last two on theta_1, theta_2) (9)
_W_DI = 54  # Delta^-1 = 1 / (1 + g e) (9)
_W_KAP = 63  # kappa = [2 alpha + g alpha^2 (x2), beta (x2)] (4)
_W_LDL = 67  # G = Phi diag(M^-1 Delta^-1) Phi^T = L D L^T: L10 L20 L30 L21 L31 L32, 1/D (10)
_W_CH = 77  # C^H (2) at the state of the last Phi
_NW = 79


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _load(Yl, Pl, l, y, prm):
    """Copy lane ``l`` of the blocks Yl, Pl into y (NY,) and prm (N_PARAMS,)."""
    for j in range(NY):
        y[j] = Yl[j * LANES + l]
    for j in range(N_PARAMS):
        prm[j] = Pl[j * LANES + l]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _phi(y, prm, w):
    """Phi (:func:`.model.constraint_terms`), M^-1 and C^H of state y into the row w (_NW,)."""
    so, co = sincos(y[TH_OBJ])
    s1, A1, B1, E1, F1, _, _, CH1 = _finger(y, prm, 0, co, so)[:8]
    s2, A2, B2, E2, F2, _, _, CH2 = _finger(y, prm, 1, co, so)[:8]
    for j in range(36):
        w[_W_PHI + j] = 0.0
    w[0] = s1 * co
    w[1] = s1 * so
    w[2] = A1
    w[TH_1] = B1
    w[DN_1] = 1.0
    w[9] = s2 * co
    w[10] = s2 * so
    w[11] = A2
    w[9 + TH_1 + 1] = B2
    w[9 + DN_1 + 1] = 1.0
    w[18] = -so
    w[19] = co
    w[20] = E1
    w[18 + TH_1] = F1
    w[18 + DT_1] = 1.0
    w[27] = -so
    w[28] = co
    w[29] = E2
    w[27 + TH_1 + 1] = F2
    w[27 + DT_1 + 1] = 1.0
    w[_W_MI + 0] = 1.0 / prm[P_MOBJ]
    w[_W_MI + 1] = 1.0 / prm[P_MOBJ]
    w[_W_MI + 2] = 1.0 / prm[P_IOBJ]
    w[_W_MI + 3] = 1.0 / prm[P_I1]
    w[_W_MI + 4] = 1.0 / prm[P_I2]
    for j in range(5, NQ):
        w[_W_MI + j] = 1.0 / prm[P_MDEF]
    w[_W_CH] = CH1
    w[_W_CH + 1] = CH2


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _ldl4(G, w, o):
    """L D L^T of the symmetric 4 x 4 G (only G[i, j], j <= i, read) into w[o:o+10]; a
    pivot <= 0 gives NaN (the state is then flagged non-finite)."""
    d0 = G[0, 0]
    i0 = 1.0 / d0 if d0 > 0.0 else math.nan
    L10 = G[1, 0] * i0
    L20 = G[2, 0] * i0
    L30 = G[3, 0] * i0
    d1 = G[1, 1] - L10 * G[1, 0]
    i1 = 1.0 / d1 if d1 > 0.0 else math.nan
    a21 = G[2, 1] - L20 * G[1, 0]
    a31 = G[3, 1] - L30 * G[1, 0]
    L21 = a21 * i1
    L31 = a31 * i1
    d2 = G[2, 2] - L20 * G[2, 0] - L21 * a21
    i2 = 1.0 / d2 if d2 > 0.0 else math.nan
    a32 = G[3, 2] - L30 * G[2, 0] - L31 * a21
    L32 = a32 * i2
    d3 = G[3, 3] - L30 * G[3, 0] - L31 * a31 - L32 * a32
    i3 = 1.0 / d3 if d3 > 0.0 else math.nan
    w[o] = L10
    w[o + 1] = L20
    w[o + 2] = L30
    w[o + 3] = L21
    w[o + 4] = L31
    w[o + 5] = L32
    w[o + 6] = i0
    w[o + 7] = i1
    w[o + 8] = i2
    w[o + 9] = i3


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _ldl4_solve(w, o, v):
    """Solve (L D L^T) x = v in place, the factors at w[o:o+10]."""
    v[1] -= w[o] * v[0]
    v[2] -= w[o + 1] * v[0] + w[o + 3] * v[1]
    v[3] -= w[o + 2] * v[0] + w[o + 4] * v[1] + w[o + 5] * v[2]
    v[3] *= w[o + 9]
    v[2] = v[2] * w[o + 8] - w[o + 5] * v[3]
    v[1] = v[1] * w[o + 7] - w[o + 3] * v[2] - w[o + 4] * v[3]
    v[0] = v[0] * w[o + 6] - w[o] * v[1] - w[o + 1] * v[2] - w[o + 2] * v[3]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _gram(w, weights, o, G):
    """G = Phi diag(w[o:o+9] * weights) Phi^T, lower triangle (4 x 4), Phi at w[0:36]."""
    for a in range(4):
        for b in range(a + 1):
            acc = 0.0
            for j in range(NQ):
                acc += w[NQ * a + j] * w[NQ * b + j] * w[o + j] * weights[j]
            G[a, b] = acc


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _setup_lanes(Yl, Pl, g, W, fresh, nl):
    """Step data of W = I - g J_W (module doc) for g = gamma h at the states Yl, into W
    (LANES, _NW); ``fresh=False`` reuses Phi and M^-1 already in W for these states."""
    y = np.empty(NY)
    prm = np.empty(N_PARAMS)
    G = np.empty((4, 4))
    ones = np.ones(NQ)
    for l in range(nl):
        w = W[l]
        _load(Yl, Pl, l, y, prm)
        if fresh:
            _phi(y, prm, w)
        for j in range(NQ):
            if j == TH_1 or j == TH_1 + 1:
                d = prm[P_KD]
                stiff = g * prm[P_KP] + g * g * prm[P_KI]
            elif j == DN_1 or j == DN_1 + 1:
                d = prm[P_CN]
                stiff = 0.0
            elif j == DT_1 or j == DT_1 + 1:
                d = prm[P_CT]
                stiff = 0.0
            else:
                d = 0.0
                stiff = 0.0
            e = w[_W_MI + j] * (d + stiff)
            w[_W_E + j] = e
            w[_W_DI + j] = 1.0 / (1.0 + g * e)
        alpha = prm[P_ALPHA]
        w[_W_KAP] = 2.0 * alpha + g * alpha * alpha
        w[_W_KAP + 1] = w[_W_KAP]
        w[_W_KAP + 2] = prm[P_BETA]
        w[_W_KAP + 3] = prm[P_BETA]
        for j in range(NQ):
            ones[j] = w[_W_DI + j]
        _gram(w, ones, _W_MI, G)
        _ldl4(G, w, _W_LDL)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _solve_lanes(R, W, Pl, g, Kout, MU, nl):
    """Solve W k = R (NY*LANES rows) per lane; Kout (NY*LANES) receives k, MU (4*LANES) the
    multiplier stage L_W k (module doc)."""
    L = LANES
    c = np.empty(NQ)
    v = np.empty(4)
    for l in range(nl):
        w = W[l]
        kp_gain = Pl[P_KP * L + l]
        ki_gain = Pl[P_KI * L + l]
        alpha = Pl[P_ALPHA * L + l]
        for j in range(NQ):
            c[j] = R[(NQ + j) * L + l]
        rzt0 = 0.0
        rzt1 = 0.0
        for i in range(2):
            t = TH_1 + i
            rq = R[t * L + l]
            rzt = R[(2 * NQ + i) * L + l] + g * rq
            mi = w[_W_MI + t]
            c[t] -= g * mi * kp_gain * rq + g * mi * ki_gain * rzt
            if i == 0:
                rzt0 = rzt
            else:
                rzt1 = rzt
        # rhs_a = sum_j Phi_aj [(e_j - kappa_a) Delta^-1_j c_j + (k_j - c2_a) r_q,j]
        #         + sum_i Phi_a,theta_i M^-1 Ki (r_z,i + g r_q,theta_i)
        for a in range(4):
            kap = w[_W_KAP + a]
            c2 = alpha * alpha if a < 2 else 0.0
            acc = 0.0
            for j in range(NQ):
                phi = w[NQ * a + j]
                if phi != 0.0:
                    kq = w[_W_MI + j] * kp_gain if (j == TH_1 or j == TH_1 + 1) else 0.0
                    acc += phi * ((w[_W_E + j] - kap) * w[_W_DI + j] * c[j]
                                  + (kq - c2) * R[j * L + l])
            acc += w[NQ * a + TH_1] * w[_W_MI + TH_1] * ki_gain * rzt0
            acc += w[NQ * a + TH_1 + 1] * w[_W_MI + TH_1 + 1] * ki_gain * rzt1
            v[a] = acc / (1.0 + g * kap)
        _ldl4_solve(w, _W_LDL, v)
        for a in range(4):
            MU[a * L + l] = v[a]
        for j in range(NQ):
            acc = 0.0
            for a in range(4):
                acc += w[NQ * a + j] * v[a]
            kp = w[_W_DI + j] * (c[j] + g * w[_W_MI + j] * acc)
            Kout[(NQ + j) * L + l] = kp
            Kout[j * L + l] = R[j * L + l] + g * kp
        for i in range(2):
            Kout[(2 * NQ + i) * L + l] = R[(2 * NQ + i) * L + l] + g * Kout[(TH_1 + i) * L + l]


@njit(cache=True, error_model="numpy")
def _ros2_lanes(Yl, Pl, h, W, fresh, K1, K2, F1, F2, Tl, I1, I2, Il, nl):
    """One ROS2 step of every lane in place; F1 (_NK*LANES) must hold f(Yl) on entry (the
    stage-1 evaluation, also the source of the step's residuals); adds the step's impulses to
    Il (4*LANES). ``fresh``: Phi in W is not that of Yl yet."""
    g = GAMMA * h
    L = LANES
    _setup_lanes(Yl, Pl, g, W, fresh, nl)
    _solve_lanes(F1, W, Pl, g, K1, I1, nl)
    # multiplier-integral stage 1: lambda(y_n) + g L_W k1
    for r in range(4):
        for l in range(nl):
            I1[r * L + l] = F1[(_R_LAM + r) * L + l] + g * I1[r * L + l]
    for i in range(NY * L):
        Tl[i] = Yl[i] + h * K1[i]
    _rhs_lanes(Tl, Pl, F2, nl)
    for i in range(NY * L):
        F2[i] = F2[i] - 2.0 * K1[i]
    _solve_lanes(F2, W, Pl, g, K2, I2, nl)
    for r in range(4):
        for l in range(nl):
            I2[r * L + l] = F2[(_R_LAM + r) * L + l] - 2.0 * I1[r * L + l] + g * I2[r * L + l]
    for i in range(NY * L):
        Yl[i] += 1.5 * h * K1[i] + 0.5 * h * K2[i]
    for i in range(4 * L):
        Il[i] += 1.5 * h * I1[i] + 0.5 * h * I2[i]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _project_lanes(Yl, Pl, W, Il, nl):
    """Project the states of lanes 0..nl-1 onto the constraint manifold, in place.

    Positions: one Newton step on C^H(q) = 0 along displacements that do not roll the
    contacts (Phi^N dq = 0: the rolling history is kept), the M-weighted shortest one,
    ``dq = M^-1 Phi^T nu``, ``(Phi M^-1 Phi^T) nu = [-C^H; 0]``. Momenta (with Phi at the new
    q): onto Phi p = 0 (C^H-dot = 0, C^N = 0), ``dp = M^-1 Phi^T mu``,
    ``mu = -(Phi M^-1 Phi^T)^-1 Phi p``, whose contact impulse mu (N s) is added to Il. W
    then holds Phi, M^-1 and C^H of the projected positions."""
    L = LANES
    y = np.empty(NY)
    prm = np.empty(N_PARAMS)
    G = np.empty((4, 4))
    v = np.empty(4)
    ones = np.ones(NQ)
    for l in range(nl):
        w = W[l]
        _load(Yl, Pl, l, y, prm)
        _phi(y, prm, w)
        _gram(w, ones, _W_MI, G)
        _ldl4(G, w, _W_LDL)
        v[0] = -w[_W_CH]
        v[1] = -w[_W_CH + 1]
        v[2] = 0.0
        v[3] = 0.0
        _ldl4_solve(w, _W_LDL, v)
        for j in range(NQ):
            acc = 0.0
            for a in range(4):
                acc += w[NQ * a + j] * v[a]
            y[j] += w[_W_MI + j] * acc
            Yl[j * L + l] = y[j]
        _phi(y, prm, w)
        _gram(w, ones, _W_MI, G)
        _ldl4(G, w, _W_LDL)
        for a in range(4):
            acc = 0.0
            for j in range(NQ):
                acc += w[NQ * a + j] * y[NQ + j]
            v[a] = -acc
        _ldl4_solve(w, _W_LDL, v)
        for a in range(4):
            Il[a * L + l] += v[a]
        for j in range(NQ):
            acc = 0.0
            for a in range(4):
                acc += w[NQ * a + j] * v[a]
            Yl[(NQ + j) * L + l] = y[NQ + j] + w[_W_MI + j] * acc


@njit(cache=True)
def _advance_block(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS, systems):
    """Advance the systems ``systems`` (at most LANES indices into Y) one call, in lanes;
    spare lanes repeat a live system and are discarded."""
    m = systems.shape[0]
    nl = m if m <= 2 else (LANES if m > LANES // 2 else LANES // 2)
    Yl = np.empty(NY * LANES)
    Pl = np.empty(_NPU * LANES)
    W = np.zeros((LANES, _NW))
    K1 = np.zeros(NY * LANES)
    K2 = np.zeros(NY * LANES)
    F1 = np.zeros(_NK * LANES)
    F2 = np.zeros(_NK * LANES)
    Tl = np.empty(NY * LANES)
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
        # Phi of the state: computed by the projection that ended the previous step
        _ros2_lanes(Yl, Pl, h, W, step == 0, K1, K2, F1, F2, Tl, I1, I2, Il, nl)
        _project_lanes(Yl, Pl, W, Il, nl)
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
                for j in range(_NW):
                    W[l, j] = W[src, j]
    if n_live == 0:
        return
    _finish_lanes(Y, U, PRM, Yl, Il, CHM, CNM, ch_limit, DIAG, FLAGS, systems, live, m, n)


@njit(cache=True, inline="always")
def _copy_lane(A, rows, src, dst):
    """Copy lane ``src`` of the structure-of-arrays block A (rows*LANES) into lane ``dst``."""
    for j in range(rows):
        A[j * LANES + dst] = A[j * LANES + src]


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
    W = np.zeros((LANES, _NW))
    K1 = np.zeros(NY * LANES)
    K2 = np.zeros(NY * LANES)
    F1 = np.zeros(_NK * LANES)
    F2 = np.zeros(_NK * LANES)
    Tl = np.zeros(NY * LANES)
    I1 = np.zeros(4 * LANES)
    I2 = np.zeros(4 * LANES)
    Il = np.zeros(4 * LANES)
    _rhs_lanes(Yl, Pl, F1, 1)
    _ros2_lanes(Yl, Pl, h, W, True, K1, K2, F1, F2, Tl, I1, I2, Il, 1)
    _project_lanes(Yl, Pl, W, Il, 1)
    for j in range(NY):
        y[j] = Yl[j * LANES]
