"""An independent reference of the chapter-5 model: equations of motion derived with sympy and
integrated with SciPy's adaptive stiff solver (test helper, not part of the package).

Only the *definitions* are shared with :mod:`softhand_env.physics.model` (they are the model): the
fingertip centres (Eqs 5.7-5.8), the holonomic constraint (Eq 5.9 with the sign fix), the
rolling constraint (Eqs 5.10-5.12) as ``d(GQ_i)/dt + (a - d_ni)(dtheta_i/dt + (-1)^i
dtheta_obj/dt) + dd_ti/dt``, the energy (Eq 5.5, cross-term sign s_i, gravity), the viscous
forces, the PID (Eq 5.42) and the CSM with Baumgarte gains (Eqs 5.19-5.24). Everything the
kernel writes out by hand (the Jacobians Phi^H, Phi^N, the velocity products b, the energy
gradient, the Schur-complement solve) is derived here symbolically and solved as the dense
13 x 13 KKT system; the time integration is SciPy's LSODA at tight tolerances instead of
fixed-step RK4.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

from softhand_env.physics.params import HandParams

_PARAM_NAMES = (
    "L", "W_fi", "a", "W_obj", "d_fi", "M_obj", "I_obj", "I_1", "I_2", "m_d", "E", "g", "c_n",
    "c_t", "Kp", "Kd", "Ki", "alpha", "beta", "s_1", "s_2", "k_b",
)


@functools.lru_cache(maxsize=1)
def _compiled():
    q = sp.symbols("x y th_o th_1 th_2 dn_1 dn_2 dt_1 dt_2", real=True)
    p = sp.symbols("vx vy w_o w_1 w_2 vdn_1 vdn_2 vdt_1 vdt_2", real=True)
    P = dict(zip(_PARAM_NAMES, sp.symbols(" ".join(_PARAM_NAMES), real=True), strict=True))
    x, y, tho = q[0], q[1], q[2]
    qv, pv = sp.Matrix(q), sp.Matrix(p)
    CH, CN, energy = [], [], P["M_obj"] * P["g"] * y
    for i in range(2):
        sgn = -1 if i == 0 else 1  # (-1)^i with i = 1 right, 2 left
        th, dn, dt = q[3 + i], q[5 + i], q[7 + i]
        Ox = -sgn * P["W_fi"] + sgn * (P["L"] * sp.sin(th) + P["d_fi"] * sp.cos(th))
        Oy = P["L"] * sp.cos(th) - P["d_fi"] * sp.sin(th)
        CH.append(
            sgn * ((x - Ox) * sp.cos(tho) + (y - Oy) * sp.sin(tho)) - (P["a"] - dn) - P["W_obj"] / 2
        )
        GQ = -(x - Ox) * sp.sin(tho) + (y - Oy) * sp.cos(tho)
        dGQ = (sp.Matrix([GQ]).jacobian(qv) * pv)[0]
        CN.append(dGQ + (P["a"] - dn) * (p[3 + i] + sgn * p[2]) + p[7 + i])
        thp = th + sgn * tho
        energy += sp.pi * P["E"] * (
            dn**3 / (3 * sp.cos(thp) ** 2)
            + P[f"s_{i + 1}"] * dn**2 * dt * sp.tan(thp)
            + P["k_b"] * dn * dt**2
        )
    CH, CN = sp.Matrix(CH), sp.Matrix(CN)
    PhiH = CH.jacobian(qv)
    PhiN = CN.jacobian(pv)
    bH = (PhiH * pv).jacobian(qv) * pv
    bN = (PhiN * pv).jacobian(qv) * pv
    f = -sp.Matrix([energy]).jacobian(qv).T
    for i in range(2):
        f[5 + i] -= P["c_n"] * p[5 + i]
        f[7 + i] -= P["c_t"] * p[7 + i]
    args = (*q, *p, *P.values())
    outs = [PhiH, PhiN, bH, bN, CH, f]
    return sp.lambdify(args, outs, modules="numpy", cse=True)


def _param_values(params: HandParams) -> list[float]:
    s1, s2 = params.cross_signs
    return [
        params.L, params.W_fi, params.a, params.W_obj, params.d_fi, params.M_obj, params.I_obj,
        params.I_1, params.I_2, params.m_deform, params.E, params.g, params.c_n, params.c_t,
        params.Kp, params.Kd, params.Ki, params.alpha, params.beta, s1, s2, params.bending,
    ]


def rhs(params: HandParams):
    """dy/dt(t, y, u) of the state [q (9), p (9), z (2)] (the kernel's layout)."""
    fn = _compiled()
    pv = _param_values(params)
    Mdiag = np.array([params.M_obj, params.M_obj, params.I_obj, params.I_1, params.I_2]
                     + [params.m_deform] * 4)
    alpha, beta = params.alpha, params.beta

    def fun(t, y, u):
        q, p, z = y[:9], y[9:18], y[18:20]
        PhiH, PhiN, bH, bN, CH, f = fn(*q, *p, *pv)
        PhiH, PhiN = np.asarray(PhiH, float), np.asarray(PhiN, float)
        f = np.asarray(f, float).ravel()
        tau = -params.Kp * (q[3:5] - u) - params.Kd * p[3:5] - params.Ki * z
        f[3:5] += tau
        Phi = np.vstack([PhiH, PhiN])
        gamma = np.concatenate([
            np.asarray(bH, float).ravel() + 2 * alpha * PhiH @ p
            + alpha**2 * np.asarray(CH, float).ravel(),
            np.asarray(bN, float).ravel() + beta * PhiN @ p,
        ])
        K = np.zeros((13, 13))
        K[:9, :9] = np.diag(Mdiag)
        K[:9, 9:] = -Phi.T
        K[9:, :9] = Phi
        sol = np.linalg.solve(K, np.concatenate([f, -gamma]))
        return np.concatenate([p, sol[:9], q[3:5] - u])

    return fun


def run_motions(params: HandParams, y0: np.ndarray, setpoints_rad, duration: float = 1.0,
                rtol: float = 1e-10, atol: float = 1e-13) -> np.ndarray:
    """Hold each set-point pair ``duration`` s from ``y0``; the states at the end of each
    motion, shape (M, 20)."""
    fun = rhs(params)
    y = np.array(y0, dtype=float)
    ends = []
    for u in np.asarray(setpoints_rad, dtype=float):
        sol = solve_ivp(fun, (0.0, duration), y, method="LSODA", args=(u,), rtol=rtol,
                        atol=atol)
        assert sol.success, sol.message
        y = sol.y[:, -1]
        ends.append(y.copy())
    return np.array(ends)
