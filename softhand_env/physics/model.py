"""Chapter-5 dynamic model of the two-finger soft hand as plain functions of (state, input, params).

State and coordinates
---------------------
Generalized coordinates (Eq 5.15, order fixed in docs/design.md), SI units::

    q = [x_obj, y_obj, theta_obj, theta_1, theta_2, d_n1, d_n2, d_t1, d_t2]   (m, m, rad, rad,
                                                                               rad, m, m, m, m)

The integrated state is ``y = [q (9), p = dq/dt (9), z (2)]`` (shape ``(20,)``), where
``z_i = integral of (theta_i - theta_i^d) dt`` (rad s) is the PID integral state of Eq 5.42.
The control input is the set-point pair ``u = (theta_1^d, theta_2^d)`` in rad; parameters are
the packed float64 vector of :func:`pack_params` (shape ``(N_PARAMS,)``).

Physics (derived here, not transcribed from the OCR-damaged Eqs 5.31-5.41)
------------------------------------------------------------------------
* Fingertip centres O_i (Eqs 5.7-5.8); contact angle theta_pi = theta_i + (-1)^i theta_obj.
* Elastic energy (Eq 5.5) with the cross-term sign s_i of docs/design.md (default -1 for both
  fingers, ``cross_term="printed"`` gives (-1)^i) and a bending factor ``k_b`` (1 = Eq 5.5)::

      P = pi E sum_i [ d_ni^3 / (3 cos^2 theta_pi) + s_i d_ni^2 d_ti tan theta_pi
                       + k_b d_ni d_ti^2 ]

  plus gravity P_gv = M_obj g y_obj; viscous forces -c_n dd_ni/dt, -c_t dd_ti/dt.
  Generalized forces are -grad(P + P_gv) (tested against finite differences).
* Holonomic normal constraints (Eq 5.9 with the sign fix of docs/design.md, w = 0)::

      C_i^H = (-1)^i [(x - O_ix) cos theta_obj + (y - O_iy) sin theta_obj] - (a - d_ni) - W_obj/2

* Non-holonomic rolling constraints (Eqs 5.10-5.12, with a - d_ni)::

      C_i^N = d(GQ_i)/dt + (a - d_ni)(dtheta_i/dt + (-1)^i dtheta_obj/dt) + dd_ti/dt,
      GQ_i  = -(x - O_ix) sin theta_obj + (y - O_iy) cos theta_obj

  C^N = Phi^N(q) p, so Phi^N = dC^N/dp (Eq 5.17), b^N = (dPhi^N/dt) p.
  Phi^H = dC^H/dq (Eq 5.21), b^H = (dPhi^H/dt) p.
* CSM (Eq 5.24) with Baumgarte stabilisation (Eqs 5.19-5.20)::

      M dp/dt = f + Phi^T lambda,   Phi dp/dt = -gamma,
      gamma = [b^H + 2 alpha Phi^H p + alpha^2 C^H ;  b^N + beta C^N]

  M is diagonal (Eq 5.14), so the KKT system is solved through its 4x4 Schur complement
  S = Phi M^-1 Phi^T (symmetric positive definite), S lambda = -gamma - Phi M^-1 f.
* PID on the finger angles (Eq 5.42): u_INi = -Kp (theta_i - theta_i^d) - Kd dtheta_i/dt - Ki z_i.

All functions are compiled with numba (``cache=True``) and written in scalar form so that the
integrator in :mod:`.kernel` allocates nothing per substep; each one is also callable
from Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.params import HandParams

#: Number of generalized coordinates.
NQ = 9
#: Length of the integrated state y = [q, p, z].
NY = 20
#: Indices into q.
X_OBJ, Y_OBJ, TH_OBJ, TH_1, TH_2, DN_1, DN_2, DT_1, DT_2 = range(9)
#: Names of q, in order.
Q_NAMES = ("x_obj", "y_obj", "theta_obj", "theta_1", "theta_2", "d_n1", "d_n2", "d_t1", "d_t2")

# Index of each parameter in the packed vector: the model's 23, then the kernels' stop limits
# (P_DN_STOP: d_n (m) at or above which integration stops, default a; P_BASE_STOP: reach past
# the fingertip base above which it stops, default inf = never; P_CH_STOP: |C^H| (m) above
# which it stops, default inf = never; see :mod:`softhand_env.physics.kernel`).
(
    P_L, P_WFI, P_A, P_WOBJ, P_DFI, P_MOBJ, P_IOBJ, P_I1, P_I2, P_MDEF, P_E, P_G, P_CN, P_CT,
    P_KP, P_KD, P_KI, P_ALPHA, P_BETA, P_DT, P_SX1, P_SX2, P_KB,
    P_DN_STOP, P_BASE_STOP, P_CH_STOP,
) = range(26)
N_PARAMS = 26
#: Entries of the packed vector the right-hand side reads (the model's parameters).
N_MODEL_PARAMS = 23

# Floating-point mode of the right-hand side: strict IEEE (no LLVM fast-math). The single-system
# kernel and the lane (SIMD) kernel compile the same source in different contexts; with no
# contraction or reassociation LLVM must evaluate it as written in both, so the batched kernel
# reproduces the single one bit for bit (fast-math {contract, arcp, afn, reassoc, nsz} is ~8%
# faster but lets the two round differently, and a grasp on the edge of being lost could then
# stop one substep apart). NaN/inf propagate as usual.
_FASTMATH = False


def pack_params(params: HandParams) -> np.ndarray:
    """Pack :class:`HandParams` into the float64 vector the compiled functions take.

    The last three entries are the kernels' stop limits at their defaults (stop at d_n >= a
    only; no stop on the fingertip base or on |C^H|); :func:`with_stop_limits` sets others.

    Returns
    -------
    ndarray, shape (N_PARAMS,)
    """
    s1, s2 = params.cross_signs
    return np.array(
        [
            params.L, params.W_fi, params.a, params.W_obj, params.d_fi, params.M_obj,
            params.I_obj, params.I_1, params.I_2, params.m_deform, params.E, params.g,
            params.c_n, params.c_t, params.Kp, params.Kd, params.Ki, params.alpha, params.beta,
            params.dt, s1, s2, params.bending, params.a, math.inf, math.inf,
        ],
        dtype=np.float64,
    )


def with_stop_limits(
    prm: np.ndarray, dn_stop: float, base_stop: float = math.inf, ch_stop: float = math.inf
) -> np.ndarray:
    """Packed parameters ``prm`` ((N_PARAMS,) or (N, N_PARAMS)) with the kernels' stop
    limits set, in place (also returned).

    Parameters
    ----------
    dn_stop : float
        d_n (m) at or above which integration stops (``FLAG_OVERCOMPRESSED``); values above
        the fingertip radius a are clipped to a (the model ends there).
    base_stop : float
        Reach past the fingertip base (dimensionless, >= 1; 1 = the base,
        :func:`softhand_env.physics.contact.beyond_base`) above which integration stops
        (``FLAG_BASE``); ``inf``: never.
    ch_stop : float
        |C^H| (m) above which integration stops (``FLAG_CONSTRAINT``); ``inf``: never.
    """
    prm[..., P_DN_STOP] = np.minimum(prm[..., P_A], dn_stop)
    prm[..., P_BASE_STOP] = base_stop
    prm[..., P_CH_STOP] = ch_stop
    return prm


def initial_finger_angle(params: HandParams) -> float:
    """Finger angle (rad) at which parallel-symmetric fingers touch the object at one point.

    Solves W_fi - L sin(t) - d_fi cos(t) - a = W_obj / 2 (zero for the paper's geometry).
    """
    rhs = params.W_fi - params.a - params.W_obj / 2
    r = math.hypot(params.L, params.d_fi)
    phi = math.atan2(params.d_fi, params.L)
    # L sin t + d_fi cos t = r sin(t + phi) = rhs
    if abs(rhs / r) > 1:
        raise ValueError("object width and finger geometry admit no point-contact state")
    return math.asin(rhs / r) - phi


def initial_state(params: HandParams) -> np.ndarray:
    """The paper's initial state (Sec 5.5.1): fingers parallel at point contact, at rest.

    The object is centred between the fingertips at the height of the fingertip centres
    (y = L for the paper's geometry), theta_obj = 0, all deformations and velocities zero.

    Returns
    -------
    ndarray, shape (NY,)
    """
    t0 = initial_finger_angle(params)
    y = np.zeros(NY)
    y[Y_OBJ] = params.L * math.cos(t0) - params.d_fi * math.sin(t0)
    y[TH_1] = y[TH_2] = t0
    return y


# sincos: Cody-Waite reduction by pi/2 (33-bit leading part, exact product for |k| < 2^20)
# and the fdlibm minimax kernels on [-pi/4, pi/4]
_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e00
_PIO2_1T = 6.07710050650619224932e-11
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11


@njit(cache=True, error_model="numpy", fastmath=False)
def sincos(x):
    """(sin x, cos x) in straight-line floating-point code (no libm call, no branch).

    Used by the model's right-hand side so that the lane kernel of :mod:`.kernel`
    vectorises across systems (a libm call would stop LLVM's loop vectoriser) and the
    single-system kernel computes exactly the same function. Error <= 1 ulp against libm for
    |x| < 1e5 (tested to 2 ulp over that range); accurate to ~|x| 1e-26 absolute up to
    |x| ~ 1.6e6, inaccurate beyond (far outside any state the kernel accepts); NaN and
    +-inf give NaN. Deliberately compiled without fast-math: reassociation would destroy the
    two-part reduction and fdlibm's compensated 1 - x^2/2. ``fastmath=False`` must stay
    explicit: numba compiles a callee that leaves fastmath unset with its caller's flags
    (should a caller ever use fast-math), and caches that version for every later caller.
    """
    k = np.floor(x * _INV_PIO2 + 0.5)
    r = (x - k * _PIO2_1) - k * _PIO2_1T
    z = r * r
    ps = _S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))
    s = r + (z * r) * (_S1 + z * ps)
    pc = z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + z * pc)
    quadrant = k - 4.0 * np.floor(0.25 * k)  # 0, 1, 2, 3 (NaN for NaN / inf)
    odd = quadrant == 1.0 or quadrant == 3.0
    s_abs = c if odd else s
    c_abs = s if odd else c
    sin_x = -s_abs if quadrant >= 2.0 else s_abs
    cos_x = -c_abs if (quadrant == 1.0 or quadrant == 2.0) else c_abs
    return sin_x, cos_x


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _finger(y, prm, i, co, so):
    """All model terms of finger i (0 = right, 1 = left) as a tuple of scalars.

    ``y`` is the state [q, p, ...] as anything indexable (a float64 array or a tuple: the
    same code serves the single-system and the lane kernels). ``co``, ``so`` are cos/sin
    theta_obj. Returns
    ``(sgn, A, B, E, F, bH, bN, CH, f_th, f_obj, f_dn, f_dt)`` where, with sgn = (-1)^i in the
    paper's numbering (i = 1 right, 2 left):

    * the holonomic row of Phi^H is ``[sgn co, sgn so, A, (theta_i) B, (d_ni) 1]``,
    * the non-holonomic row of Phi^N is ``[-so, co, E, (theta_i) F, (d_ti) 1]``,
    * ``bH``, ``bN`` are (dPhi/dt) p of the two rows, ``CH`` the holonomic residual (m),
    * ``f_th``, ``f_obj``, ``f_dn``, ``f_dt`` the finger's share of -grad P (Eq 5.5) on
      theta_i, theta_obj, d_ni, d_ti, with the viscous forces on d_ni, d_ti.
    """
    L = prm[P_L]
    dfi = prm[P_DFI]
    sgn = -1.0 if i == 0 else 1.0
    ti = TH_1 + i
    ni = DN_1 + i
    di = DT_1 + i
    si, ci = sincos(y[ti])
    # fingertip centre O_i (Eqs 5.7-5.8) and its first/second derivatives w.r.t. theta_i
    Ox = -sgn * prm[P_WFI] + sgn * (L * si + dfi * ci)
    Oy = L * ci - dfi * si
    Ox1 = sgn * (L * ci - dfi * si)
    Oy1 = -(L * si + dfi * ci)
    Ox2 = sgn * Oy1
    Oy2 = -L * ci + dfi * si
    # contact angle theta_pi = theta_i + sgn * theta_obj
    cp = ci * co - sgn * si * so
    sp = si * co + sgn * ci * so
    vx = y[NQ + X_OBJ]
    vy = y[NQ + Y_OBJ]
    wo = y[NQ + TH_OBJ]
    wi = y[NQ + ti]
    vdn = y[NQ + ni]
    dn = y[ni]
    dt = y[di]
    rx = y[X_OBJ] - Ox
    ry = y[Y_OBJ] - Oy
    vrx = vx - Ox1 * wi
    vry = vy - Oy1 * wi
    rho = prm[P_A] - dn
    # holonomic constraint (Eq 5.9 with the sign fix of docs/design.md)
    A = sgn * (-rx * so + ry * co)
    B = sgn * (-Ox1 * co - Oy1 * so)
    CH = sgn * (rx * co + ry * so) - rho - 0.5 * prm[P_WOBJ]
    bH = sgn * (
        -(Ox2 * co + Oy2 * so) * wi * wi
        + 2.0 * wo * (-vrx * so + vry * co)
        - wo * wo * (rx * co + ry * so)
    )
    # non-holonomic rolling constraint (Eq 5.12): C^N = Phi^N p
    E = -rx * co - ry * so + sgn * rho
    F = Ox1 * so - Oy1 * co + rho
    dE = -vrx * co + rx * so * wo - vry * so - ry * co * wo - sgn * vdn
    dF = Ox2 * wi * so + Ox1 * co * wo - Oy2 * wi * co + Oy1 * so * wo - vdn
    bN = -co * wo * vx - so * wo * vy + dE * wo + dF * wi
    # -grad of this finger's terms of Eq 5.5, viscous damping on d_ni, d_ti
    piE = math.pi * prm[P_E]
    kb = prm[P_KB]
    sx = prm[P_SX1 + i]
    icp = 1.0 / cp
    tp = sp * icp
    ic2 = icp * icp
    dP_dn = piE * (dn * dn * ic2 + 2.0 * sx * dn * dt * tp + kb * dt * dt)
    dP_dt = piE * (sx * dn * dn * tp + 2.0 * kb * dn * dt)
    dP_dtp = piE * ((2.0 / 3.0) * dn * dn * dn * tp * ic2 + sx * dn * dn * dt * ic2)
    f_dn = -dP_dn - prm[P_CN] * vdn
    f_dt = -dP_dt - prm[P_CT] * y[NQ + di]
    return sgn, A, B, E, F, bH, bN, CH, -dP_dtp, -sgn * dP_dtp, f_dn, f_dt


@njit(cache=True)
def _all_terms(q, p, prm, Phi, b, C, f):
    """Fill Phi (4, 9), b (4,), C (2,) and f (9,) (without PID torques) for both fingers."""
    y = np.empty(2 * NQ)
    y[:NQ] = q[:NQ]
    y[NQ:] = p[:NQ]
    so, co = sincos(y[TH_OBJ])
    for r in range(4):
        for j in range(NQ):
            Phi[r, j] = 0.0
    for j in range(NQ):
        f[j] = 0.0
    f[Y_OBJ] = -prm[P_MOBJ] * prm[P_G]
    for i in range(2):
        sgn, A, B, E, F, bH, bN, CH, f_th, f_obj, f_dn, f_dt = _finger(y, prm, i, co, so)
        Phi[i, X_OBJ] = sgn * co
        Phi[i, Y_OBJ] = sgn * so
        Phi[i, TH_OBJ] = A
        Phi[i, TH_1 + i] = B
        Phi[i, DN_1 + i] = 1.0
        Phi[2 + i, X_OBJ] = -so
        Phi[2 + i, Y_OBJ] = co
        Phi[2 + i, TH_OBJ] = E
        Phi[2 + i, TH_1 + i] = F
        Phi[2 + i, DT_1 + i] = 1.0
        b[i] = bH
        b[2 + i] = bN
        C[i] = CH
        f[TH_1 + i] = f_th
        f[TH_OBJ] += f_obj
        f[DN_1 + i] = f_dn
        f[DT_1 + i] = f_dt


@njit(cache=True)
def elastic_energy(q, prm):
    """Elastic energy of both fingertips, Eq 5.5 with the configured cross-term signs (J).

    Parameters
    ----------
    q : ndarray, shape (>= 9,)
    prm : ndarray, shape (N_PARAMS,)
    """
    piE = math.pi * prm[P_E]
    total = 0.0
    for i in range(2):
        sgn = -1.0 if i == 0 else 1.0
        tp_angle = q[TH_1 + i] + sgn * q[TH_OBJ]
        cp = math.cos(tp_angle)
        dn = q[DN_1 + i]
        dt = q[DT_1 + i]
        total += piE * (
            dn**3 / (3.0 * cp * cp)
            + prm[P_SX1 + i] * dn * dn * dt * math.tan(tp_angle)
            + prm[P_KB] * dn * dt * dt
        )
    return total


@njit(cache=True)
def potential_energy(q, prm):
    """Elastic plus gravitational energy P + M_obj g y_obj (J)."""
    return elastic_energy(q, prm) + prm[P_MOBJ] * prm[P_G] * q[Y_OBJ]


@njit(cache=True)
def constraint_terms(q, p, prm, Phi, b, C):
    """Constraint Jacobian, velocity-product terms and holonomic residuals.

    Parameters
    ----------
    q, p : ndarray, shape (9,)
        Generalized coordinates and velocities.
    prm : ndarray, shape (N_PARAMS,)
    Phi : ndarray, shape (4, 9), output
        Rows 0-1: Phi^H = dC^H/dq; rows 2-3: Phi^N = dC^N/dp.
    b : ndarray, shape (4,), output
        (dPhi/dt) p for each row, so that d/dt(Phi p) = Phi dp/dt + b.
    C : ndarray, shape (2,), output
        Holonomic residuals C^H (m).
    """
    f = np.empty(NQ)
    _all_terms(q, p, prm, Phi, b, C, f)


@njit(cache=True)
def potential_forces(q, p, prm, f):
    """Generalized forces -grad(P + P_gv) minus viscous damping, into f (9,) (N, N m)."""
    Phi = np.empty((4, NQ))
    b = np.empty(4)
    C = np.empty(2)
    _all_terms(q, p, prm, Phi, b, C, f)


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def pid_torque(theta, setpoint, omega, z, kp, kd, ki):
    """PID joint torque of Eq 5.42 (N m): ``-Kp (theta - theta^d) - Kd omega - Ki z``.

    The single definition, inlined into :func:`csm_terms` and :func:`pid_torques`.
    ``theta``, ``setpoint`` in rad, ``omega`` in rad/s, ``z`` the PID integral (rad s).
    """
    return -kp * (theta - setpoint) - kd * omega - ki * z


@njit(cache=True)
def pid_torques(y, u, prm, tau):
    """PID joint torques of Eq 5.42 (N m) for state y (20,) and set-points u (2,) into tau (2,)."""
    for i in range(2):
        tau[i] = pid_torque(
            y[TH_1 + i], u[i], y[NQ + TH_1 + i], y[2 * NQ + i], prm[P_KP], prm[P_KD], prm[P_KI]
        )


@njit(cache=True)
def pid_torques_batch(Y, U, PRM, TAU):
    """:func:`pid_torques` for each row of Y (N, 20), U (N, 2), PRM (N, N_PARAMS) into TAU."""
    for s in range(Y.shape[0]):
        pid_torques(Y[s], U[s], PRM[s], TAU[s])


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def _inverse_pivot(d):
    """1 / d for a pivot d > 0 of a positive definite matrix, NaN otherwise (branch-free)."""
    return 1.0 / d if d > 0.0 else math.nan


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH, inline="always")
def csm_terms(y, u, prm):
    """The model's right-hand side as a tuple of scalars: the single definition of the physics.

    Solves M dp/dt = f + Phi^T lambda, Phi dp/dt = -gamma through the 4x4 Schur complement
    S = Phi M^-1 Phi^T (written out with the sparsity of Phi; M is diagonal).

    ``y`` (state, >= 20 entries), ``u`` (2 set-points) and ``prm`` (N_PARAMS) may be float64
    arrays or tuples of floats: :func:`csm_rhs` passes arrays, the lane kernel of
    :mod:`softhand_env.physics.kernel` tuples loaded from its structure-of-arrays block, and the
    function is inlined (numba IR) into both, so that both compile the same source (in
    strict IEEE arithmetic, see ``_FASTMATH``: the two give bit-identical results).

    Returns ``(dp (9 accelerations), dz1, dz2, CH1, CH2, CN1, CN2, tau1, tau2, lH1, lH2, lN1,
    lN2)``, flattened: 21 floats (see :func:`csm_rhs` for the meaning).
    """
    so, co = sincos(y[TH_OBJ])
    s1, A1, B1, E1, F1, bH1, bN1, CH1, fth1, fo1, fdn1, fdt1 = _finger(y, prm, 0, co, so)
    s2, A2, B2, E2, F2, bH2, bN2, CH2, fth2, fo2, fdn2, fdt2 = _finger(y, prm, 1, co, so)
    vx = y[NQ + X_OBJ]
    vy = y[NQ + Y_OBJ]
    wo = y[NQ + TH_OBJ]
    w1 = y[NQ + TH_1]
    w2 = y[NQ + TH_2]
    # PID torques (Eq 5.42)
    tau1 = pid_torque(y[TH_1], u[0], w1, y[2 * NQ], prm[P_KP], prm[P_KD], prm[P_KI])
    tau2 = pid_torque(y[TH_2], u[1], w2, y[2 * NQ + 1], prm[P_KP], prm[P_KD], prm[P_KI])
    fx = 0.0
    fy = -prm[P_MOBJ] * prm[P_G]
    fo = fo1 + fo2
    ft1 = fth1 + tau1
    ft2 = fth2 + tau2
    mx = 1.0 / prm[P_MOBJ]
    mo = 1.0 / prm[P_IOBJ]
    m1 = 1.0 / prm[P_I1]
    m2 = 1.0 / prm[P_I2]
    md = 1.0 / prm[P_MDEF]
    # constraint velocities Phi p: holonomic C^H-dot and non-holonomic C^N
    cv = co * vx + so * vy
    cw = -so * vx + co * vy
    dCH1 = s1 * cv + A1 * wo + B1 * w1 + y[NQ + DN_1]
    dCH2 = s2 * cv + A2 * wo + B2 * w2 + y[NQ + DN_2]
    CN1 = cw + E1 * wo + F1 * w1 + y[NQ + DT_1]
    CN2 = cw + E2 * wo + F2 * w2 + y[NQ + DT_2]
    # Phi M^-1 f
    cf = mx * (co * fx + so * fy)
    wf = mx * (-so * fx + co * fy)
    of = mo * fo
    alpha = prm[P_ALPHA]
    beta = prm[P_BETA]
    a2 = alpha * alpha
    r0 = -(bH1 + 2.0 * alpha * dCH1 + a2 * CH1) - (s1 * cf + A1 * of + B1 * m1 * ft1 + md * fdn1)
    r1 = -(bH2 + 2.0 * alpha * dCH2 + a2 * CH2) - (s2 * cf + A2 * of + B2 * m2 * ft2 + md * fdn2)
    r2 = -(bN1 + beta * CN1) - (wf + E1 * of + F1 * m1 * ft1 + md * fdt1)
    r3 = -(bN2 + beta * CN2) - (wf + E2 * of + F2 * m2 * ft2 + md * fdt2)
    # Schur complement S = Phi M^-1 Phi^T, rows/cols ordered [H1, H2, N1, N2]
    S00 = mx + mo * A1 * A1 + m1 * B1 * B1 + md
    S11 = mx + mo * A2 * A2 + m2 * B2 * B2 + md
    S22 = mx + mo * E1 * E1 + m1 * F1 * F1 + md
    S33 = mx + mo * E2 * E2 + m2 * F2 * F2 + md
    S10 = s1 * s2 * mx + mo * A1 * A2
    S20 = mo * A1 * E1 + m1 * B1 * F1
    S30 = mo * A1 * E2
    S21 = mo * A2 * E1
    S31 = mo * A2 * E2 + m2 * B2 * F2
    S32 = mx + mo * E1 * E2
    # S = L D L^T (unrolled; no square roots), a_ij = L_ij D_j, i_j = 1 / D_j. S is positive
    # definite, so a pivot D_j <= 0 (or NaN) only comes from a diverged state: it gives NaN,
    # as the square root of a Cholesky factorisation would, and the state is flagged
    # non-finite
    i0 = _inverse_pivot(S00)
    L10 = S10 * i0
    L20 = S20 * i0
    L30 = S30 * i0
    a21 = S21 - L20 * S10
    a31 = S31 - L30 * S10
    i1 = _inverse_pivot(S11 - L10 * S10)
    L21 = a21 * i1
    L31 = a31 * i1
    a32 = S32 - L30 * S20 - L31 * a21
    i2 = _inverse_pivot(S22 - L20 * S20 - L21 * a21)
    L32 = a32 * i2
    i3 = _inverse_pivot(S33 - L30 * S30 - L31 * a31 - L32 * a32)
    # forward substitution, scaling by D^-1, back substitution
    fw1 = r1 - L10 * r0
    fw2 = r2 - L20 * r0 - L21 * fw1
    fw3 = r3 - L30 * r0 - L31 * fw1 - L32 * fw2
    lN2 = fw3 * i3
    lN1 = fw2 * i2 - L32 * lN2
    lH2 = fw1 * i1 - L21 * lN1 - L31 * lN2
    lH1 = r0 * i0 - L10 * lH2 - L20 * lN1 - L30 * lN2
    # accelerations M^-1 (f + Phi^T lambda)
    lc = s1 * lH1 + s2 * lH2
    lw = lN1 + lN2
    return (
        mx * (fx + co * lc - so * lw),
        mx * (fy + so * lc + co * lw),
        mo * (fo + A1 * lH1 + A2 * lH2 + E1 * lN1 + E2 * lN2),
        m1 * (ft1 + B1 * lH1 + F1 * lN1),
        m2 * (ft2 + B2 * lH2 + F2 * lN2),
        md * (fdn1 + lH1),
        md * (fdn2 + lH2),
        md * (fdt1 + lN1),
        md * (fdt2 + lN2),
        y[TH_1] - u[0],
        y[TH_2] - u[1],
        CH1, CH2, CN1, CN2, tau1, tau2, lH1, lH2, lN1, lN2,
    )


@njit(cache=True, error_model="numpy", fastmath=_FASTMATH)
def csm_rhs(y, u, prm, dy, diag):
    """Time derivative of the integrated state under the CSM (Eq 5.24) and PID (Eq 5.42).

    Parameters
    ----------
    y : ndarray, shape (20,)
        State [q, p, z].
    u : ndarray, shape (2,)
        Finger-angle set-points (rad).
    prm : ndarray, shape (N_PARAMS,)
    dy : ndarray, shape (20,), output
        dy/dt.
    diag : ndarray, shape (>= 10,), output
        C^H (m, 2), C^N (m/s, 2), PID torques (N m, 2), lambda (N, N, N, N: 4) at ``y``.
    """
    t = csm_terms(y, u, prm)
    for j in range(NQ):
        dy[j] = y[NQ + j]
    for j in range(NQ + 2):
        dy[NQ + j] = t[j]
    for j in range(N_DIAG):
        diag[j] = t[NQ + 2 + j]


#: Length of the ``diag`` output of :func:`csm_rhs`.
N_DIAG = 10


@njit(cache=True)
def constraint_residuals(y, prm, out):
    """Holonomic residuals C^H (m) and non-holonomic residuals C^N (m/s) into out (4,)."""
    Phi = np.empty((4, NQ))
    b = np.empty(4)
    C = np.empty(2)
    constraint_terms(y[:NQ], y[NQ : 2 * NQ], prm, Phi, b, C)
    out[0] = C[0]
    out[1] = C[1]
    for r in range(2, 4):
        s = 0.0
        for j in range(NQ):
            s += Phi[r, j] * y[NQ + j]
        out[r] = s


