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
begin with a set-point jump, whose transient (the finger damping mode, ~0.1 ms, then the
joints settling over a few ms) is the part of the motion a millisecond step resolves worst, so
a call starts with a geometric ramp ``H/8, H/8, H/4, H/2`` (together one step H, the
integrator's step ``ros2_dt``), takes up to :data:`FINE_STEPS` steps of H, and covers the
quasi-static rest in equal steps of at most :data:`TAIL_FACTOR` H (:func:`step_schedule`). A
call shorter than H is the ramp scaled to T; one of at most (1 + FINE_STEPS) H covers the rest
after the ramp in equal steps of at most H. On the paper's motions 1-8 (20 ms and 200 ms
calls) this schedule stays within 0.04 mm / 0.08 deg of RK4 at 0.1 ms along the trajectory and
0.035 mm / 0.026 deg at the ends of the motions, with 15 steps per 20 ms call (23 with steps
of H throughout) and 105 per 200 ms call (203); ``docs/integrator.md`` has the measurements.

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
structure-of-arrays lanes of :mod:`.kernel` (the same right-hand side source, vectorised). The
step data, the solves and the projection are lane kernels of the same kind: one loop over the
lanes of a block whose body is straight-line code (the non-zero entries of Phi written out,
the 4 x 4 factorisation and solves unrolled, M^-1 and 1 / (1 + g kappa) computed once per
block or step instead of divided inside), so that LLVM vectorises them across systems; a
block's step data also live in structure-of-arrays form (``W[row * LANES + lane]``). Blocks run
in parallel above :data:`PARALLEL_MIN_WORK` system-steps, on the calling thread below, unless
the caller chooses (``parallel``; :class:`~softhand_env.physics.hand.HandPhysics` measures which
is faster, :mod:`softhand_env.physics.dispatch`). A
system integrated alone or in any batch follows the same arithmetic, so it ends bit for bit
equal. All systems of a call must share ``dt`` (one schedule).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
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
    TH_OBJ,
    _finger,
    sincos,
)

#: gamma of ROS2 (L-stable choice 1 + 1/sqrt(2)).
GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: Fractions of the step H of the ramp a call starts with (they sum to 1).
RAMP = (0.125, 0.125, 0.25, 0.5)
#: Steps of H after the ramp, before the steps grow to at most TAIL_FACTOR H.
FINE_STEPS = 3
#: The largest step of a call, in units of H (the quasi-static rest of a control period).
TAIL_FACTOR = 2.0


@njit(cache=True)
def _schedule(T, H):
    """(ramp steps, fine steps, fine step size, tail steps, tail step size) of a call of T
    seconds with step H (:func:`step_schedule`)."""
    if T <= H * (1.0 + 1e-9):
        return 4, 0, 0.0, 0, 0.0
    rest = T - H
    if rest <= FINE_STEPS * H * (1.0 + 1e-9):
        k = int(math.ceil(rest / H - 1e-9))
        return 4, k, rest / k, 0, 0.0
    tail = rest - FINE_STEPS * H
    k = int(math.ceil(tail / (TAIL_FACTOR * H) - 1e-9))
    return 4, FINE_STEPS, H, k, tail / k


def step_schedule(T: float, H: float) -> np.ndarray:
    """Step sizes (s) a call of ``T`` seconds takes with the integrator step ``H`` (s).

    A ramp ``H/8, H/8, H/4, H/2`` (scaled to T if T <= H), then up to :data:`FINE_STEPS`
    steps of H (equal steps of at most H if they cover the rest), then equal steps of at most
    :data:`TAIL_FACTOR` H covering the rest; the sizes sum to T up to round-off. Returns shape
    (n_steps,).
    """
    if not (T > 0.0 and H > 0.0):
        raise ValueError(f"T and H must be > 0 (got {T!r}, {H!r})")
    n_ramp, k_fine, h_fine, k_tail, h_tail = _schedule(T, H)
    scale = T if k_fine == 0 else H
    return np.array([f * scale for f in RAMP] + [h_fine] * k_fine + [h_tail] * k_tail)


def largest_step(H: float) -> float:
    """The largest step (s) of any call with the integrator step ``H`` (s): TAIL_FACTOR H."""
    return TAIL_FACTOR * H


def rhs_evaluations(T: float, H: float) -> int:
    """Right-hand-side evaluations of one call of ``T`` seconds at step ``H``: two per step
    and one at the final state (its residuals), as :func:`.kernel.advance` takes four per
    substep and one at the end."""
    return 2 * len(step_schedule(T, H)) + 1


# Step data of a block in structure-of-arrays form, as the lane kernel's blocks: row r of lane
# l at W[r * LANES + l]. Every lane kernel below is one loop over the lanes whose body is
# straight-line code (the sparse entries of Phi written out, the 4 x 4 factorisation and
# solves unrolled), so that LLVM vectorises it across systems like :func:`.kernel._rhs_lanes`.
# Phi at the state: the entries of :func:`.model._finger` (the holonomic rows are
# [sgn co, sgn so, A, (theta_i) B, (d_ni) 1], the rolling ones [-so, co, E, (theta_i) F,
# (d_ti) 1], sgn = -1, +1) and C^H there
_W_CO, _W_SO, _W_A1, _W_A2, _W_B1, _W_B2, _W_E1, _W_E2, _W_F1, _W_F2, _W_CH1, _W_CH2 = range(12)
# M^-1 (x and y share 1 / M_obj, the deformations 1 / m_def), set once per block
_W_MX, _W_MO, _W_M1, _W_M2, _W_MD = range(12, 17)
# e = M^-1 (D + g Kp + g^2 Ki) and Delta^-1 = 1 / (1 + g e) on theta_1, theta_2, d_n, d_t
# (zero and one on the object's coordinates)
_W_ET1, _W_ET2, _W_EN, _W_ETT, _W_DT1, _W_DT2, _W_DN, _W_DTT = range(17, 25)
# kappa of the holonomic and the rolling rows, and 1 / (1 + g kappa) of both
_W_KAPH, _W_KAPN, _W_IKH, _W_IKN = 25, 26, 27, 28
# G = Phi diag(M^-1 Delta^-1) Phi^T = L D L^T: L10 L20 L30 L21 L31 L32, 1/D (10)
_W_LDL = 29
_NW = 39


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _phi_lane(Yl, Pl, l):
    """(co, so, A1, A2, B1, B2, E1, E2, F1, F2, CH1, CH2) of lane ``l`` of the block Yl, Pl:
    the entries of Phi (:func:`.model._finger`) and C^H at its positions."""
    L = LANES
    y = (
        Yl[0 * L + l], Yl[1 * L + l], Yl[2 * L + l], Yl[3 * L + l], Yl[4 * L + l],
        Yl[5 * L + l], Yl[6 * L + l], Yl[7 * L + l], Yl[8 * L + l], Yl[9 * L + l],
        Yl[10 * L + l], Yl[11 * L + l], Yl[12 * L + l], Yl[13 * L + l], Yl[14 * L + l],
        Yl[15 * L + l], Yl[16 * L + l], Yl[17 * L + l],
    )
    prm = (
        Pl[0 * L + l], Pl[1 * L + l], Pl[2 * L + l], Pl[3 * L + l], Pl[4 * L + l],
        Pl[5 * L + l], Pl[6 * L + l], Pl[7 * L + l], Pl[8 * L + l], Pl[9 * L + l],
        Pl[10 * L + l], Pl[11 * L + l], Pl[12 * L + l], Pl[13 * L + l], Pl[14 * L + l],
        Pl[15 * L + l], Pl[16 * L + l], Pl[17 * L + l], Pl[18 * L + l], Pl[19 * L + l],
        Pl[20 * L + l], Pl[21 * L + l], Pl[22 * L + l],
    )
    so, co = sincos(y[TH_OBJ])
    _, A1, B1, E1, F1, _, _, CH1 = _finger(y, prm, 0, co, so)[:8]
    _, A2, B2, E2, F2, _, _, CH2 = _finger(y, prm, 1, co, so)[:8]
    return co, so, A1, A2, B1, B2, E1, E2, F1, F2, CH1, CH2


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _store_phi(W, l, t):
    """Store the tuple ``t`` of :func:`_phi_lane` in rows _W_CO.._W_CH2 of lane ``l``."""
    L = LANES
    W[_W_CO * L + l] = t[0]
    W[_W_SO * L + l] = t[1]
    W[_W_A1 * L + l] = t[2]
    W[_W_A2 * L + l] = t[3]
    W[_W_B1 * L + l] = t[4]
    W[_W_B2 * L + l] = t[5]
    W[_W_E1 * L + l] = t[6]
    W[_W_E2 * L + l] = t[7]
    W[_W_F1 * L + l] = t[8]
    W[_W_F2 * L + l] = t[9]
    W[_W_CH1 * L + l] = t[10]
    W[_W_CH2 * L + l] = t[11]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _load_phi(W, l):
    """The tuple of :func:`_phi_lane` stored in W for lane ``l``."""
    L = LANES
    return (
        W[_W_CO * L + l], W[_W_SO * L + l], W[_W_A1 * L + l], W[_W_A2 * L + l],
        W[_W_B1 * L + l], W[_W_B2 * L + l], W[_W_E1 * L + l], W[_W_E2 * L + l],
        W[_W_F1 * L + l], W[_W_F2 * L + l], W[_W_CH1 * L + l], W[_W_CH2 * L + l],
    )


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _ldl4(G00, G10, G11, G20, G21, G22, G30, G31, G32, G33):
    """L D L^T of the symmetric 4 x 4 G: (L10, L20, L30, L21, L31, L32, 1/D0, .., 1/D3); a
    pivot <= 0 gives NaN (the state is then flagged non-finite)."""
    i0 = 1.0 / G00 if G00 > 0.0 else math.nan
    L10 = G10 * i0
    L20 = G20 * i0
    L30 = G30 * i0
    d1 = G11 - L10 * G10
    i1 = 1.0 / d1 if d1 > 0.0 else math.nan
    a21 = G21 - L20 * G10
    a31 = G31 - L30 * G10
    L21 = a21 * i1
    L31 = a31 * i1
    d2 = G22 - L20 * G20 - L21 * a21
    i2 = 1.0 / d2 if d2 > 0.0 else math.nan
    a32 = G32 - L30 * G20 - L31 * a21
    L32 = a32 * i2
    d3 = G33 - L30 * G30 - L31 * a31 - L32 * a32
    i3 = 1.0 / d3 if d3 > 0.0 else math.nan
    return L10, L20, L30, L21, L31, L32, i0, i1, i2, i3


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _gram_ldl(t, mx, mo, m1, d1, m2, d2, md, dn, dt):
    """L D L^T (:func:`_ldl4`) of G = Phi diag(M^-1 d) Phi^T for Phi of the tuple ``t``
    (:func:`_phi_lane`), M^-1 = (mx, mx, mo, m1, m2, md, md, md, md) and
    d = (1, 1, 1, d1, d2, dn, dn, dt, dt), each entry summed over the non-zero products of
    the two rows in coordinate order (the x and y products of a holonomic and a rolling row
    cancel exactly and are left out)."""
    co, so, A1, A2, B1, B2, E1, E2, F1, F2 = t[:10]
    xc = co * co * mx
    xs = so * so * mx
    wn = md * dn
    wt = md * dt
    G00 = xc + xs + A1 * A1 * mo + B1 * B1 * m1 * d1 + wn
    G10 = -co * co * mx + (-so * so * mx) + A2 * A1 * mo
    G11 = xc + xs + A2 * A2 * mo + B2 * B2 * m2 * d2 + wn
    G20 = E1 * A1 * mo + F1 * B1 * m1 * d1
    G21 = E1 * A2 * mo
    G22 = xs + xc + E1 * E1 * mo + F1 * F1 * m1 * d1 + wt
    G30 = E2 * A1 * mo
    G31 = E2 * A2 * mo + F2 * B2 * m2 * d2
    G32 = xs + xc + E2 * E1 * mo
    G33 = xs + xc + E2 * E2 * mo + F2 * F2 * m2 * d2 + wt
    return _ldl4(G00, G10, G11, G20, G21, G22, G30, G31, G32, G33)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _ldl4_solve(f, v0, v1, v2, v3):
    """Solve (L D L^T) x = v for the factors ``f`` of :func:`_ldl4`; returns x (4 floats)."""
    v1 -= f[0] * v0
    v2 -= f[1] * v0 + f[3] * v1
    v3 -= f[2] * v0 + f[4] * v1 + f[5] * v2
    v3 *= f[9]
    v2 = v2 * f[8] - f[5] * v3
    v1 = v1 * f[7] - f[3] * v2 - f[4] * v3
    v0 = v0 * f[6] - f[0] * v1 - f[1] * v2 - f[2] * v3
    return v0, v1, v2, v3


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _phi_t(t, v0, v1, v2, v3):
    """Phi^T v (9 floats) for Phi of the tuple ``t`` (:func:`_phi_lane`)."""
    co, so, A1, A2, B1, B2, E1, E2, F1, F2 = t[:10]
    return (
        -co * v0 + co * v1 + (-so) * v2 + (-so) * v3,
        -so * v0 + so * v1 + co * v2 + co * v3,
        A1 * v0 + A2 * v1 + E1 * v2 + E2 * v3,
        B1 * v0 + F1 * v2,
        B2 * v1 + F2 * v3,
        v0, v1, v2, v3,
    )


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _phi_v(t, v):
    """Phi v (4 floats) of a 9-vector ``v`` (indexable) for Phi of the tuple ``t``."""
    co, so, A1, A2, B1, B2, E1, E2, F1, F2 = t[:10]
    return (
        -co * v[0] + (-so) * v[1] + A1 * v[2] + B1 * v[3] + v[5],
        co * v[0] + so * v[1] + A2 * v[2] + B2 * v[4] + v[6],
        -so * v[0] + co * v[1] + E1 * v[2] + F1 * v[3] + v[7],
        -so * v[0] + co * v[1] + E2 * v[2] + F2 * v[4] + v[8],
    )


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _get9(A, row, l):
    """Rows row..row+8 of lane ``l`` of the block A, as a 9-tuple."""
    L = LANES
    return (A[(row + 0) * L + l], A[(row + 1) * L + l], A[(row + 2) * L + l],
            A[(row + 3) * L + l], A[(row + 4) * L + l], A[(row + 5) * L + l],
            A[(row + 6) * L + l], A[(row + 7) * L + l], A[(row + 8) * L + l])


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _put9(A, row, l, v):
    """Store the 9-tuple ``v`` in rows row..row+8 of lane ``l`` of the block A."""
    L = LANES
    A[(row + 0) * L + l] = v[0]
    A[(row + 1) * L + l] = v[1]
    A[(row + 2) * L + l] = v[2]
    A[(row + 3) * L + l] = v[3]
    A[(row + 4) * L + l] = v[4]
    A[(row + 5) * L + l] = v[5]
    A[(row + 6) * L + l] = v[6]
    A[(row + 7) * L + l] = v[7]
    A[(row + 8) * L + l] = v[8]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _axpy9(A, row, l, x, mx, mo, m1, m2, md, d):
    """Rows row..row+8 of lane ``l`` of A = x + M^-1 d (9-tuples x, d; M^-1 as in
    :func:`_gram_ldl`)."""
    _put9(A, row, l, (x[0] + mx * d[0], x[1] + mx * d[1], x[2] + mo * d[2],
                      x[3] + m1 * d[3], x[4] + m2 * d[4], x[5] + md * d[5],
                      x[6] + md * d[6], x[7] + md * d[7], x[8] + md * d[8]))


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _masses_lanes(Pl, W, nl):
    """M^-1 of lanes 0..nl-1 of a block (parameters Pl, _NPU*LANES) into W (_NW*LANES)."""
    L = LANES
    for l in range(nl):
        W[_W_MX * L + l] = 1.0 / Pl[P_MOBJ * L + l]
        W[_W_MO * L + l] = 1.0 / Pl[P_IOBJ * L + l]
        W[_W_M1 * L + l] = 1.0 / Pl[P_I1 * L + l]
        W[_W_M2 * L + l] = 1.0 / Pl[P_I2 * L + l]
        W[_W_MD * L + l] = 1.0 / Pl[P_MDEF * L + l]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _setup_lanes(Pl, g, W, nl):
    """Step data of W = I - g J_W (module doc) for g = gamma h into W, from the Phi and M^-1
    in W (those of the states the step starts from)."""
    L = LANES
    for l in range(nl):
        kd = Pl[P_KD * L + l]
        stiff = g * Pl[P_KP * L + l] + g * g * Pl[P_KI * L + l]
        m1 = W[_W_M1 * L + l]
        m2 = W[_W_M2 * L + l]
        md = W[_W_MD * L + l]
        et1 = m1 * (kd + stiff)
        et2 = m2 * (kd + stiff)
        en = md * (Pl[P_CN * L + l] + 0.0)
        ett = md * (Pl[P_CT * L + l] + 0.0)
        dt1 = 1.0 / (1.0 + g * et1)
        dt2 = 1.0 / (1.0 + g * et2)
        dn = 1.0 / (1.0 + g * en)
        dtt = 1.0 / (1.0 + g * ett)
        W[_W_ET1 * L + l] = et1
        W[_W_ET2 * L + l] = et2
        W[_W_EN * L + l] = en
        W[_W_ETT * L + l] = ett
        W[_W_DT1 * L + l] = dt1
        W[_W_DT2 * L + l] = dt2
        W[_W_DN * L + l] = dn
        W[_W_DTT * L + l] = dtt
        alpha = Pl[P_ALPHA * L + l]
        kh = 2.0 * alpha + g * alpha * alpha
        kn = Pl[P_BETA * L + l]
        W[_W_KAPH * L + l] = kh
        W[_W_KAPN * L + l] = kn
        W[_W_IKH * L + l] = 1.0 / (1.0 + g * kh)
        W[_W_IKN * L + l] = 1.0 / (1.0 + g * kn)
        f = _gram_ldl(_load_phi(W, l), W[_W_MX * L + l], W[_W_MO * L + l], m1, dt1, m2,
                      dt2, md, dn, dtt)
        W[(_W_LDL + 0) * L + l] = f[0]
        W[(_W_LDL + 1) * L + l] = f[1]
        W[(_W_LDL + 2) * L + l] = f[2]
        W[(_W_LDL + 3) * L + l] = f[3]
        W[(_W_LDL + 4) * L + l] = f[4]
        W[(_W_LDL + 5) * L + l] = f[5]
        W[(_W_LDL + 6) * L + l] = f[6]
        W[(_W_LDL + 7) * L + l] = f[7]
        W[(_W_LDL + 8) * L + l] = f[8]
        W[(_W_LDL + 9) * L + l] = f[9]


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _term(phi, e, kap, di, c, kq, c2, rq):
    """phi [(e - kappa) Delta^-1 c + (k - c2) r_q]: one coordinate's share of the multiplier
    stage's right-hand side (module doc)."""
    return phi * ((e - kap) * di * c + (kq - c2) * rq)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _solve_lanes(R, W, Pl, g, Kout, MU, nl):
    """Solve W k = R (NY*LANES rows) per lane; Kout (NY*LANES) receives k, MU (4*LANES) the
    multiplier stage L_W k (module doc)."""
    L = LANES
    for l in range(nl):
        kp_gain = Pl[P_KP * L + l]
        ki_gain = Pl[P_KI * L + l]
        alpha = Pl[P_ALPHA * L + l]
        t = _load_phi(W, l)
        co, so, A1, A2, B1, B2, E1, E2, F1, F2 = t[:10]
        mx = W[_W_MX * L + l]
        mo = W[_W_MO * L + l]
        m1 = W[_W_M1 * L + l]
        m2 = W[_W_M2 * L + l]
        md = W[_W_MD * L + l]
        et1 = W[_W_ET1 * L + l]
        et2 = W[_W_ET2 * L + l]
        en = W[_W_EN * L + l]
        ett = W[_W_ETT * L + l]
        dt1 = W[_W_DT1 * L + l]
        dt2 = W[_W_DT2 * L + l]
        dn = W[_W_DN * L + l]
        dtt = W[_W_DTT * L + l]
        kh = W[_W_KAPH * L + l]
        kn = W[_W_KAPN * L + l]
        rq = (R[0 * L + l], R[1 * L + l], R[2 * L + l], R[3 * L + l], R[4 * L + l],
              R[5 * L + l], R[6 * L + l], R[7 * L + l], R[8 * L + l])
        rzt0 = R[(2 * NQ) * L + l] + g * rq[3]
        rzt1 = R[(2 * NQ + 1) * L + l] + g * rq[4]
        c = (
            R[9 * L + l], R[10 * L + l], R[11 * L + l],
            R[12 * L + l] - (g * m1 * kp_gain * rq[3] + g * m1 * ki_gain * rzt0),
            R[13 * L + l] - (g * m2 * kp_gain * rq[4] + g * m2 * ki_gain * rzt1),
            R[14 * L + l], R[15 * L + l], R[16 * L + l], R[17 * L + l],
        )
        kq1 = m1 * kp_gain
        kq2 = m2 * kp_gain
        c2 = alpha * alpha
        # rhs_a = sum_j Phi_aj [(e_j - kappa_a) Delta^-1_j c_j + (k_j - c2_a) r_q,j]
        #         + sum_i Phi_a,theta_i M^-1 Ki (r_z,i + g r_q,theta_i), non-zero Phi_aj only
        r0 = (_term(-co, 0.0, kh, 1.0, c[0], 0.0, c2, rq[0])
              + _term(-so, 0.0, kh, 1.0, c[1], 0.0, c2, rq[1])
              + _term(A1, 0.0, kh, 1.0, c[2], 0.0, c2, rq[2])
              + _term(B1, et1, kh, dt1, c[3], kq1, c2, rq[3])
              + _term(1.0, en, kh, dn, c[5], 0.0, c2, rq[5])
              + B1 * m1 * ki_gain * rzt0)
        r1 = (_term(co, 0.0, kh, 1.0, c[0], 0.0, c2, rq[0])
              + _term(so, 0.0, kh, 1.0, c[1], 0.0, c2, rq[1])
              + _term(A2, 0.0, kh, 1.0, c[2], 0.0, c2, rq[2])
              + _term(B2, et2, kh, dt2, c[4], kq2, c2, rq[4])
              + _term(1.0, en, kh, dn, c[6], 0.0, c2, rq[6])
              + B2 * m2 * ki_gain * rzt1)
        r2 = (_term(-so, 0.0, kn, 1.0, c[0], 0.0, 0.0, rq[0])
              + _term(co, 0.0, kn, 1.0, c[1], 0.0, 0.0, rq[1])
              + _term(E1, 0.0, kn, 1.0, c[2], 0.0, 0.0, rq[2])
              + _term(F1, et1, kn, dt1, c[3], kq1, 0.0, rq[3])
              + _term(1.0, ett, kn, dtt, c[7], 0.0, 0.0, rq[7])
              + F1 * m1 * ki_gain * rzt0)
        r3 = (_term(-so, 0.0, kn, 1.0, c[0], 0.0, 0.0, rq[0])
              + _term(co, 0.0, kn, 1.0, c[1], 0.0, 0.0, rq[1])
              + _term(E2, 0.0, kn, 1.0, c[2], 0.0, 0.0, rq[2])
              + _term(F2, et2, kn, dt2, c[4], kq2, 0.0, rq[4])
              + _term(1.0, ett, kn, dtt, c[8], 0.0, 0.0, rq[8])
              + F2 * m2 * ki_gain * rzt1)
        f = (
            W[(_W_LDL + 0) * L + l], W[(_W_LDL + 1) * L + l], W[(_W_LDL + 2) * L + l],
            W[(_W_LDL + 3) * L + l], W[(_W_LDL + 4) * L + l], W[(_W_LDL + 5) * L + l],
            W[(_W_LDL + 6) * L + l], W[(_W_LDL + 7) * L + l], W[(_W_LDL + 8) * L + l],
            W[(_W_LDL + 9) * L + l],
        )
        ikh = W[_W_IKH * L + l]
        ikn = W[_W_IKN * L + l]
        v0, v1, v2, v3 = _ldl4_solve(f, r0 * ikh, r1 * ikh, r2 * ikn, r3 * ikn)
        MU[0 * L + l] = v0
        MU[1 * L + l] = v1
        MU[2 * L + l] = v2
        MU[3 * L + l] = v3
        pt = _phi_t(t, v0, v1, v2, v3)
        kp = (
            c[0] + g * mx * pt[0], c[1] + g * mx * pt[1], c[2] + g * mo * pt[2],
            dt1 * (c[3] + g * m1 * pt[3]), dt2 * (c[4] + g * m2 * pt[4]),
            dn * (c[5] + g * md * pt[5]), dn * (c[6] + g * md * pt[6]),
            dtt * (c[7] + g * md * pt[7]), dtt * (c[8] + g * md * pt[8]),
        )
        _put9(Kout, NQ, l, kp)
        kq = (rq[0] + g * kp[0], rq[1] + g * kp[1], rq[2] + g * kp[2], rq[3] + g * kp[3],
              rq[4] + g * kp[4], rq[5] + g * kp[5], rq[6] + g * kp[6], rq[7] + g * kp[7],
              rq[8] + g * kp[8])
        _put9(Kout, 0, l, kq)
        Kout[(2 * NQ) * L + l] = R[(2 * NQ) * L + l] + g * kq[3]
        Kout[(2 * NQ + 1) * L + l] = R[(2 * NQ + 1) * L + l] + g * kq[4]


@njit(cache=True, error_model="numpy", inline="always")
def _axpby(D, od, X, ox, a, Y, oy, rows, nl):
    """D[od + i] = X[ox + i] + a Y[oy + i] over ``rows`` rows (of LANES entries) of the lanes
    0..nl-1 of structure-of-arrays blocks: for nl > 2 one flat unit-stride loop over whole
    rows (vectorised; the spare lanes hold finite values nobody reads), else lane by lane
    (a vectorised loop of one or two iterations per row costs more than the arithmetic)."""
    L = LANES
    if nl > 2:
        for i in range(rows * L):
            D[od + i] = X[ox + i] + a * Y[oy + i]
    else:
        for l in range(nl):
            for j in range(rows):
                D[od + j * L + l] = X[ox + j * L + l] + a * Y[oy + j * L + l]


@njit(cache=True, error_model="numpy", inline="always")
def _axpbypcz(D, X, a, Y, b, Z, rows, nl):
    """D[i] = X[i] + (a Y[i] + b Z[i]) over ``rows`` rows of lanes 0..nl-1 (as
    :func:`_axpby`)."""
    L = LANES
    if nl > 2:
        for i in range(rows * L):
            D[i] = X[i] + (a * Y[i] + b * Z[i])
    else:
        for l in range(nl):
            for j in range(rows):
                i = j * L + l
                D[i] = X[i] + (a * Y[i] + b * Z[i])


@njit(cache=True, error_model="numpy")
def _ros2_lanes(Yl, Pl, h, W, K1, K2, F1, F2, Tl, I1, I2, Il, nl):
    """One ROS2 step of lanes 0..nl-1 in place; F1 (_NK*LANES) must hold f(Yl) on entry (the
    stage-1 evaluation, also the source of the step's residuals) and W the Phi of Yl; adds
    the step's impulses to Il (4*LANES)."""
    g = GAMMA * h
    L = LANES
    _setup_lanes(Pl, g, W, nl)
    _solve_lanes(F1, W, Pl, g, K1, I1, nl)
    # multiplier-integral stage 1: lambda(y_n) + g L_W k1
    _axpby(I1, 0, F1, _R_LAM * L, g, I1, 0, 4, nl)
    _axpby(Tl, 0, Yl, 0, h, K1, 0, NY, nl)
    _rhs_lanes(Tl, Pl, F2, nl)
    _axpby(F2, 0, F2, 0, -2.0, K1, 0, NY, nl)
    _solve_lanes(F2, W, Pl, g, K2, I2, nl)
    # multiplier-integral stage 2: lambda(y_n + h k1) - 2 kI1 + g L_W k2
    _axpby(I2, 0, F2, _R_LAM * L, g, I2, 0, 4, nl)
    _axpby(I2, 0, I2, 0, -2.0, I1, 0, 4, nl)
    _axpbypcz(Yl, Yl, 1.5 * h, K1, 0.5 * h, K2, NY, nl)
    _axpbypcz(Il, Il, 1.5 * h, I1, 0.5 * h, I2, 4, nl)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _phi_lanes(Yl, Pl, W, nl):
    """Phi and C^H of the states of lanes 0..nl-1 into W."""
    for l in range(nl):
        _store_phi(W, l, _phi_lane(Yl, Pl, l))


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def _project_lanes(Yl, Pl, W, Il, nl):
    """Project the states of lanes 0..nl-1 onto the constraint manifold, in place.

    Positions: one Newton step on C^H(q) = 0 along displacements that do not roll the
    contacts (Phi^N dq = 0: the rolling history is kept), the M-weighted shortest one,
    ``dq = M^-1 Phi^T nu``, ``(Phi M^-1 Phi^T) nu = [-C^H; 0]``. Momenta (with Phi at the new
    q): onto Phi p = 0 (C^H-dot = 0, C^N = 0), ``dp = M^-1 Phi^T mu``,
    ``mu = -(Phi M^-1 Phi^T)^-1 Phi p``, whose contact impulse mu (N s) is added to Il. W
    then holds Phi and C^H of the projected positions."""
    L = LANES
    for l in range(nl):
        mx = W[_W_MX * L + l]
        mo = W[_W_MO * L + l]
        m1 = W[_W_M1 * L + l]
        m2 = W[_W_M2 * L + l]
        md = W[_W_MD * L + l]
        t = _phi_lane(Yl, Pl, l)
        f = _gram_ldl(t, mx, mo, m1, 1.0, m2, 1.0, md, 1.0, 1.0)
        v = _ldl4_solve(f, -t[10], -t[11], 0.0, 0.0)
        _axpy9(Yl, 0, l, _get9(Yl, 0, l), mx, mo, m1, m2, md, _phi_t(t, v[0], v[1], v[2], v[3]))
        t = _phi_lane(Yl, Pl, l)
        _store_phi(W, l, t)
        f = _gram_ldl(t, mx, mo, m1, 1.0, m2, 1.0, md, 1.0, 1.0)
        p = _get9(Yl, NQ, l)
        w = _phi_v(t, p)
        v = _ldl4_solve(f, -w[0], -w[1], -w[2], -w[3])
        Il[0 * L + l] += v[0]
        Il[1 * L + l] += v[1]
        Il[2 * L + l] += v[2]
        Il[3 * L + l] += v[3]
        _axpy9(Yl, NQ, l, p, mx, mo, m1, m2, md, _phi_t(t, v[0], v[1], v[2], v[3]))


@njit(cache=True)
def _advance_block(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS, systems):
    """Advance the systems ``systems`` (at most LANES indices into Y) one call, in lanes;
    spare lanes repeat a live system and are discarded."""
    m = systems.shape[0]
    nl = m if m <= 2 else (LANES if m > LANES // 2 else LANES // 2)
    Yl = np.empty(NY * LANES)
    Pl = np.empty(_NPU * LANES)
    W = np.zeros(_NW * LANES)
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
    # every lane when the flat loops of _axpby run over whole rows (nl > 2), else the nl lanes
    # the lane loops read
    for l in range(LANES if nl > 2 else nl):
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
    n_ramp, k_fine, h_fine, k_tail, h_tail = _schedule(T, H)
    scale = T if k_fine == 0 else H
    _masses_lanes(Pl, W, nl)
    _phi_lanes(Yl, Pl, W, nl)
    n_live = m
    t = 0.0
    for step in range(n_ramp + k_fine + k_tail):
        if step < n_ramp:
            h = RAMP[step] * scale
        else:
            h = h_fine if step < n_ramp + k_fine else h_tail
        _rhs_lanes(Yl, Pl, F1, nl)
        # Phi of the state in W: from the projection that ended the previous step
        _ros2_lanes(Yl, Pl, h, W, K1, K2, F1, F2, Tl, I1, I2, Il, nl)
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
                _copy_lane(W, _NW, src, l)
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
def advance_batch_parallel(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS):
    """:func:`advance_batch` with the blocks over numba's threads, without its checks (one
    ``dt`` for every system, ``H`` > 0: the caller's to keep); callable from compiled
    code."""
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


#: System-steps (systems x ROS2 steps) below which :func:`advance_batch` runs on the calling
#: thread unless told otherwise: about 4 ms of work (some 85 ns a system-step in lanes; 512
#: systems over a 20 ms control step are 11,776). A parallel region costs its launch and, on
#: a loaded machine, the wait for a descheduled worker thread; with the OpenMP threading
#: layer's default wait policy that wait measured 15-25 ms a call on a shared 2-core
#: machine, twenty times the work of 512 systems.
PARALLEL_MIN_WORK = 50_000


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
    parallel: bool | None = None,
) -> None:
    """Advance ``N`` systems over ``n`` substeps of their ``dt`` with ROS2 at step ``H``.

    Arguments and outputs as :func:`softhand_env.physics.kernel.advance_batch`, plus

    H : float
        The ROS2 step (s) (the steps of :func:`step_schedule`).

    ``DIAG[:, 2]`` receives ``n`` for a completed call, else the elapsed time in whole
    substeps of ``dt`` at the fatal stop. Every system must have the same ``dt``
    (``ValueError`` otherwise).

    ``parallel``: True runs the blocks over numba's threads, False on the calling thread
    (the results are the same either way); None (default) runs a call of fewer than
    :data:`PARALLEL_MIN_WORK` system-steps on the calling thread
    (:class:`~softhand_env.physics.hand.HandPhysics` chooses by measured time instead,
    :mod:`softhand_env.physics.dispatch`).
    """
    if not H > 0.0:
        raise ValueError(f"H must be > 0 (got {H!r})")
    _check_uniform_dt(PRM)
    N = Y.shape[0]
    if parallel is None:
        parallel = N * len(step_schedule(n * float(PRM[0, P_DT]), H)) >= PARALLEL_MIN_WORK
    if parallel:
        advance_batch_parallel(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS)
    else:
        advance_batch_serial(Y, U, PRM, n, H, ch_limit, DIAG, FLAGS)


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
    "PARALLEL_MIN_WORK",
    "FINE_STEPS",
    "RAMP",
    "TAIL_FACTOR",
    "advance",
    "advance_batch",
    "advance_batch_parallel",
    "advance_batch_serial",
    "rhs_evaluations",
    "ros2_step",
    "largest_step",
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
    W = np.zeros(_NW * LANES)
    K1 = np.zeros(NY * LANES)
    K2 = np.zeros(NY * LANES)
    F1 = np.zeros(_NK * LANES)
    F2 = np.zeros(_NK * LANES)
    Tl = np.zeros(NY * LANES)
    I1 = np.zeros(4 * LANES)
    I2 = np.zeros(4 * LANES)
    Il = np.zeros(4 * LANES)
    _masses_lanes(Pl, W, 1)
    _phi_lanes(Yl, Pl, W, 1)
    _rhs_lanes(Yl, Pl, F1, 1)
    _ros2_lanes(Yl, Pl, h, W, K1, K2, F1, F2, Tl, I1, I2, Il, 1)
    _project_lanes(Yl, Pl, W, Il, 1)
    for j in range(NY):
        y[j] = Yl[j * LANES]
