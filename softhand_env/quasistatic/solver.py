"""Quasi-static LMEE manipulation model of chapter 4 (Eqs 4.1-4.15): model and solver.

Two fingers with one rotary joint each hold a rigid planar object between hemispherical soft
fingertips; the finger angles (theta_1, theta_2) are the inputs, given as a path of small
increments. Per increment the configuration ``z = (x, y, theta_obj, d_1, d_2)`` (m, m, rad, m,
m) minimises the fingertip energy (Eq 4.11) on the normal and rolling constraints; it is found
by Newton's method on the KKT equations, warm-started from the previous increment, with a
second-order check (:func:`solve_path`, results in :class:`QuasiStaticPath`). The rolling
distances follow the discretised Eq 5.10 (``scheme="trapezoid"`` by default, ``"paper"`` for
the printed backward-Euler sums), so the equilibrium is path-dependent.

The constraints, the reading of the LMEE algorithm, the convergence order of the two schemes,
the degenerate (just touching) increments and the fingertip-base flags: ``docs/quasistatic.md``.
Units are SI throughout (m, rad, Pa, J, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.params import HandParams, load_hand_params

#: Default finger-angle increment (rad) of the handling process: 0.1 deg.
DEFAULT_STEP = math.radians(0.1)
#: Total squeeze d_1 + d_2 (m) below which an increment is solved in the degenerate mode.
D_DEGENERATE = 1e-7
#: Allowed negative total squeeze (m) before a path counts as opening the grasp.
D_OPEN_TOL = 1e-9
#: Rolling discretisations (name -> kernel code): "trapezoid" rolling radius
#: a - (d^(k-1) + d^k)/2, "paper" a - d^k (backward Euler, Eq 4.10 as printed).
SCHEMES = {"trapezoid": 0, "paper": 1}

# status codes of the kernel
_OK = 0
_NOT_CONVERGED = 1
_OPENED = 2
_OVERCOMPRESSED = 3
_NONFINITE = 4


# ---------------------------------------------------------------------------------------------
# compiled kernel
# ---------------------------------------------------------------------------------------------


@njit(cache=True)
def energy_scalar(d, theta_p, E):
    """Closed-form fingertip energy pi E d^3 / (3 cos^2 theta_p) (Eq 2.14), scalar (J).

    Compiled copy of :func:`softhand_env.physics.contact.potential_energy` for the inner loop.
    """
    c = math.cos(theta_p)
    return math.pi * E * d * d * d / (3.0 * c * c)


@njit(cache=True)
def _lu_solve(A, b):
    """Solve A x = b (n x n) by Gaussian elimination with partial pivoting (copies inputs).

    Returns (x, ok); ok is False for a numerically singular matrix.
    """
    n = A.shape[0]
    M = A.copy()
    x = b.copy()
    scale = 0.0
    for i in range(n):
        for j in range(n):
            scale = max(scale, abs(M[i, j]))
    if scale == 0.0:
        return x, False
    for k in range(n):
        p = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                p = i
        if big <= 1e-18 * scale:
            return x, False
        if p != k:
            for j in range(n):
                t = M[k, j]
                M[k, j] = M[p, j]
                M[p, j] = t
            t = x[k]
            x[k] = x[p]
            x[p] = t
        for i in range(k + 1, n):
            f = M[i, k] / M[k, k]
            if f != 0.0:
                for j in range(k, n):
                    M[i, j] -= f * M[k, j]
                x[i] -= f * x[k]
    for k in range(n - 1, -1, -1):
        acc = x[k]
        for j in range(k + 1, n):
            acc -= M[k, j] * x[j]
        x[k] = acc / M[k, k]
    return x, True


@njit(cache=True)
def _det(A):
    """Determinant of a small square matrix by elimination with partial pivoting."""
    n = A.shape[0]
    M = A.copy()
    det = 1.0
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if M[p, k] == 0.0:
            return 0.0
        if p != k:
            for j in range(n):
                t = M[k, j]
                M[k, j] = M[p, j]
                M[p, j] = t
            det = -det
        det *= M[k, k]
        for i in range(k + 1, n):
            f = M[i, k] / M[k, k]
            for j in range(k, n):
                M[i, j] -= f * M[k, j]
    return det


@njit(cache=True)
def _terms(z, th, zp, thp, sp, prm, scheme, g, J, Hg, gP, HP):
    """Constraints, energy and their first and second derivatives at one increment.

    Parameters
    ----------
    z : (5,) x, y, theta_obj, d_1, d_2 (m, m, rad, m, m) -- current unknowns
    th : (2,) finger angles of this increment (rad)
    zp, thp, sp : previous increment's z (5,), finger angles (2,), rolling distances (2,)
    prm : (6,) L, W_fi, a, W_obj, d_fi, E (SI)
    scheme : 0 trapezoid, 1 paper (backward Euler)
    g, J, Hg, gP, HP : outputs (4,), (4, 5), (4, 5, 5), (5,), (5, 5)

    Rows of g: N_1, N_2, R_1, R_2. Returns the energy P (J).
    """
    L, Wfi, a, Wobj, dfi, E = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    x, y, to = z[0], z[1], z[2]
    c = math.cos(to)
    s = math.sin(to)
    k3 = math.pi * E / 3.0
    J[:, :] = 0.0
    Hg[:, :, :] = 0.0
    gP[:] = 0.0
    HP[:, :] = 0.0
    P = 0.0
    for i in range(2):
        sig = -1.0 if i == 0 else 1.0
        ti = th[i]
        Ox = -sig * Wfi + sig * (L * math.sin(ti) + dfi * math.cos(ti))
        Oy = L * math.cos(ti) - dfi * math.sin(ti)
        u = x - Ox
        v = y - Oy
        di = z[3 + i]
        GQ = -u * s + v * c
        ucvs = u * c + v * s
        # normal constraint
        g[i] = sig * ucvs - (a - di) - 0.5 * Wobj
        J[i, 0] = sig * c
        J[i, 1] = sig * s
        J[i, 2] = sig * GQ
        J[i, 3 + i] = 1.0
        Hg[i, 0, 2] = -sig * s
        Hg[i, 2, 0] = -sig * s
        Hg[i, 1, 2] = sig * c
        Hg[i, 2, 1] = sig * c
        Hg[i, 2, 2] = -sig * ucvs
        # rolling constraint with the discretised history sum
        dthi = ti - thp[i]
        rel = dthi + sig * (to - zp[2])
        if scheme == 0:
            rho = a - 0.5 * (zp[3 + i] + di)
            drho = -0.5
        else:
            rho = a - di
            drho = -1.0
        r = 2 + i
        g[r] = GQ - sp[i] + rho * rel
        J[r, 0] = -s
        J[r, 1] = c
        J[r, 2] = -ucvs + rho * sig
        J[r, 3 + i] = drho * rel
        Hg[r, 0, 2] = -c
        Hg[r, 2, 0] = -c
        Hg[r, 1, 2] = -s
        Hg[r, 2, 1] = -s
        Hg[r, 2, 2] = -GQ
        Hg[r, 2, 3 + i] = drho * sig
        Hg[r, 3 + i, 2] = drho * sig
        # energy
        phi = ti + sig * to
        cp = math.cos(phi)
        sec2 = 1.0 / (cp * cp)
        tn = math.tan(phi)
        P += energy_scalar(di, phi, E)
        gP[3 + i] = 3.0 * k3 * di * di * sec2
        gP[2] += 2.0 * k3 * di * di * di * sec2 * tn * sig
        HP[3 + i, 3 + i] = 6.0 * k3 * di * sec2
        HP[2, 3 + i] = 6.0 * k3 * di * di * sec2 * tn * sig
        HP[3 + i, 2] = HP[2, 3 + i]
        HP[2, 2] += k3 * di * di * di * (4.0 * sec2 * tn * tn + 2.0 * sec2 * sec2)
    return P


@njit(cache=True)
def _null_vector(J):
    """Unit vector spanning the null space of a (4, 5) matrix (cofactor expansion)."""
    Z = np.zeros(5)
    sub = np.zeros((4, 4))
    for j in range(5):
        col = 0
        for jj in range(5):
            if jj == j:
                continue
            for i in range(4):
                sub[i, col] = J[i, jj]
            col += 1
        Z[j] = (-1.0) ** j * _det(sub)
    nrm = math.sqrt(np.sum(Z * Z))
    if nrm > 0.0:
        Z /= nrm
    return Z


@njit(cache=True)
def _kkt_scaled_residual(gP, J, lam, a):
    """Relative first-order residual |grad P - J^T lam| / |grad P| (theta row scaled by 1/a)."""
    num = 0.0
    den = 0.0
    for j in range(5):
        acc = gP[j]
        for k in range(4):
            acc -= J[k, j] * lam[k]
        w = 1.0 / a if j == 2 else 1.0
        num = max(num, abs(acc) * w)
        den = max(den, abs(gP[j]) * w)
    if den <= 0.0:
        return math.nan
    return num / den


@njit(cache=True)
def _least_squares_multipliers(gP, J):
    """Multipliers minimising |grad P - J^T lam| (normal equations J J^T lam = J grad P)."""
    A = J @ J.T
    b = J @ gP
    lam, ok = _lu_solve(A, b)
    if not ok:
        lam[:] = 0.0
    return lam


@njit(cache=True)
def _newton(z0, lam0, degenerate, th, zp, thp, sp, prm, scheme, max_iter, tol_c, tol_k):
    """Newton iteration for one increment; returns (z, lam, converged, iterations).

    Regular mode: the 9 KKT equations grad P - J^T lam = 0, g = 0. Degenerate mode
    (d_1 + d_2 ~ 0): g = 0, d_1 cos(theta_p2) - d_2 cos(theta_p1) = 0 and lam = 0.
    Converged means max|g| <= tol_c (m) and the stationarity residual <= tol_k relative
    (regular) or the split equation <= tol_c (degenerate), checked after >= 1 update.
    """
    a = prm[2]
    z = z0.copy()
    lam = lam0.copy()
    g = np.zeros(4)
    J = np.zeros((4, 5))
    Hg = np.zeros((4, 5, 5))
    gP = np.zeros(5)
    HP = np.zeros((5, 5))
    K = np.zeros((9, 9))
    F = np.zeros(9)
    for it in range(1, max_iter + 1):
        _terms(z, th, zp, thp, sp, prm, scheme, g, J, Hg, gP, HP)
        K[:, :] = 0.0
        if not degenerate:
            stat = 0.0
            fscale = 0.0
            for i in range(5):
                for j in range(5):
                    acc = HP[i, j]
                    for q in range(4):
                        acc -= lam[q] * Hg[q, i, j]
                    K[i, j] = acc
                acc = gP[i]
                for q in range(4):
                    acc -= J[q, i] * lam[q]
                    K[i, 5 + q] = -J[q, i]
                    K[5 + q, i] = J[q, i]
                F[i] = -acc
                w = 1.0 / a if i == 2 else 1.0
                stat = max(stat, abs(acc) * w)
                fscale = max(fscale, abs(gP[i]) * w)
            for q in range(4):
                F[5 + q] = -g[q]
            ok_k = stat <= tol_k * fscale
        else:
            for q in range(4):
                for j in range(5):
                    K[q, j] = J[q, j]
                F[q] = -g[q]
            tp1 = th[0] - z[2]
            tp2 = th[1] + z[2]
            c1 = math.cos(tp1)
            c2 = math.cos(tp2)
            F[4] = -(z[3] * c2 - z[4] * c1)
            K[4, 2] = -z[3] * math.sin(tp2) - z[4] * math.sin(tp1)
            K[4, 3] = c2
            K[4, 4] = -c1
            for q in range(4):
                K[5 + q, 5 + q] = 1.0
                F[5 + q] = -lam[q]
            ok_k = abs(F[4]) <= tol_c
        if it > 1 and ok_k and np.max(np.abs(g)) <= tol_c:
            return z, lam, True, it - 1
        dx, ok = _lu_solve(K, F)
        if not ok:
            return z, lam, False, it
        for i in range(5):
            z[i] += dx[i]
        for q in range(4):
            lam[q] += dx[5 + q]
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(lam))):
            return z, lam, False, it
    return z, lam, False, max_iter


@njit(cache=True)
def _solve_path_kernel(theta, z0, s0, prm, scheme, max_iter, tol_c, tol_k, out_z, out_s,
                       out_lam, out_P, out_res, out_kkt, out_hred, out_iter, out_deg):
    """Solve every increment of a finger-angle path; returns (status, index reached).

    ``theta`` is (N, 2); row 0 is the state ``z0``, ``s0``. Outputs are filled for rows
    0..index; status is one of the module's ``_OK`` ... codes.
    """
    N = theta.shape[0]
    a = prm[2]
    g = np.zeros(4)
    J = np.zeros((4, 5))
    Hg = np.zeros((4, 5, 5))
    gP = np.zeros(5)
    HP = np.zeros((5, 5))
    out_z[0, :] = z0
    out_s[0, :] = s0
    P0 = _terms(z0, theta[0], z0, theta[0], s0, prm, scheme, g, J, Hg, gP, HP)
    lam = _least_squares_multipliers(gP, J)
    out_lam[0, :] = lam
    out_P[0] = P0
    out_res[0] = np.max(np.abs(g))
    out_deg[0] = z0[3] + z0[4] < D_DEGENERATE
    out_kkt[0] = math.nan if out_deg[0] else _kkt_scaled_residual(gP, J, lam, a)
    Hl = HP.copy()
    for k in range(4):
        Hl -= lam[k] * Hg[k]
    Z = _null_vector(J)
    out_hred[0] = Z @ Hl @ Z
    out_iter[0] = 0
    for n in range(1, N):
        zp = out_z[n - 1]
        thp = theta[n - 1]
        th = theta[n]
        sp = out_s[n - 1]
        # predictor: secant extrapolation when this increment continues the previous one
        z = zp.copy()
        if n >= 2:
            d0 = theta[n - 1] - theta[n - 2]
            d1 = th - thp
            nn = d0[0] * d0[0] + d0[1] * d0[1]
            if nn > 0.0:
                r = (d0[0] * d1[0] + d0[1] * d1[1]) / nn
                e0 = d1[0] - r * d0[0]
                e1 = d1[1] - r * d0[1]
                if r > 0.0 and e0 * e0 + e1 * e1 <= 1e-12 * nn:
                    z = zp + r * (zp - out_z[n - 2])
        lam = out_lam[n - 1].copy()
        # attempt 0 in the mode the predictor suggests; attempt 1 switches mode: a degenerate
        # solve that ends with a real squeeze is polished by the KKT Newton, a KKT solve that
        # ends at (almost) zero squeeze is redone with the limit condition
        degenerate = z[3] + z[4] < D_DEGENERATE
        zs = z
        ls = lam
        it = 0
        converged = False
        for attempt in range(2):
            z1, lam1, converged, k = _newton(zs, ls, degenerate, th, zp, thp, sp, prm, scheme,
                                             max_iter, tol_c, tol_k)
            it += k
            if attempt == 0 and degenerate and z1[3] + z1[4] >= D_DEGENERATE:
                _terms(z1, th, zp, thp, sp, prm, scheme, g, J, Hg, gP, HP)
                zs = z1
                ls = _least_squares_multipliers(gP, J)
                degenerate = False
            elif attempt == 0 and not degenerate and z1[3] + z1[4] < D_DEGENERATE:
                degenerate = True
            else:
                break
        z = z1
        lam = lam1
        P = _terms(z, th, zp, thp, sp, prm, scheme, g, J, Hg, gP, HP)
        if not (np.all(np.isfinite(z)) and np.isfinite(P)):
            return _NONFINITE, n - 1
        out_z[n, :] = z
        out_iter[n] = it
        out_deg[n] = degenerate
        if z[3] + z[4] < -D_OPEN_TOL:
            return _OPENED, n
        if z[3] >= a or z[4] >= a:
            return _OVERCOMPRESSED, n
        # rolling distances from the discretised Eq 5.10
        for i in range(2):
            sig = -1.0 if i == 0 else 1.0
            rel = th[i] - thp[i] + sig * (z[2] - zp[2])
            rho = a - 0.5 * (zp[3 + i] + z[3 + i]) if scheme == 0 else a - z[3 + i]
            out_s[n, i] = sp[i] - rho * rel
        if degenerate:
            lam = _least_squares_multipliers(gP, J)
        out_lam[n, :] = lam
        out_P[n] = P
        out_res[n] = np.max(np.abs(g))
        out_kkt[n] = math.nan if degenerate else _kkt_scaled_residual(gP, J, lam, a)
        Hl = HP.copy()
        for q in range(4):
            Hl -= lam[q] * Hg[q]
        Z = _null_vector(J)
        out_hred[n] = Z @ Hl @ Z
        if not converged:
            return _NOT_CONVERGED, n
    return _OK, N - 1


# ---------------------------------------------------------------------------------------------
# Python API
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class QuasiStaticState:
    """One quasi-static configuration (SI units).

    Attributes
    ----------
    theta : ndarray, shape (2,)
        Finger angles (theta_1 right, theta_2 left), rad, positive inward.
    x, y : float
        Object centre in Sigma_R (m).
    theta_obj : float
        Object orientation (rad, counter-clockwise positive).
    d : ndarray, shape (2,)
        Fingertip compressions (d_1, d_2) (m).
    s : ndarray, shape (2,)
        Rolling distances (s_1, s_2) of Eq 5.10 (m); the rolling constraint is GQ_i = s_i.
    """

    theta: np.ndarray
    x: float
    y: float
    theta_obj: float
    d: np.ndarray
    s: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """(x, y, theta_obj) as an array (m, m, rad)."""
        return np.array([self.x, self.y, self.theta_obj])


@dataclass(frozen=True)
class QuasiStaticPath:
    """Solution of :func:`solve_path` along N finger-angle samples (row 0 = start state).

    Attributes
    ----------
    theta : ndarray, shape (N, 2)
        Finger angles (rad).
    x, y, theta_obj : ndarray, shape (N,)
        Object pose (m, m, rad).
    d, s : ndarray, shape (N, 2)
        Compressions and rolling distances (m).
    multipliers : ndarray, shape (N, 4)
        KKT multipliers of (N_1, N_2, R_1, R_2) (N): the normal forces and the tangential
        (rolling) constraint forces the fingertips exert.
    energy : ndarray, shape (N,)
        Elastic energy P of Eq 4.11 (J).
    theta_p : ndarray, shape (N, 2)
        Contact angles theta_1 - theta_obj, theta_2 + theta_obj (rad).
    constraint_residual : ndarray, shape (N,)
        max |N_i|, |R_i| after the increment (m).
    kkt_residual : ndarray, shape (N,)
        max|grad P - J^T lambda| / max|grad P| with the theta_obj row divided by a
        (dimensionless); NaN on degenerate rows.
    reduced_hessian : ndarray, shape (N,)
        Z^T H_L Z on the unit null vector Z of the constraint Jacobian (mixed units, J/m^2
        for a purely translational Z); > 0 means a strict local minimum on the manifold.
    iterations : ndarray of int, shape (N,)
        Newton iterations per increment.
    degenerate : ndarray of bool, shape (N,)
        Rows with d_1 + d_2 < D_DEGENERATE solved by the limit condition.
    base_violation : ndarray of bool, shape (N, 2)
        Contact circle beyond the fingertip base (Eq 2.14 over-predicts there).
    op : ndarray of int, shape (N,)
        Operation number of each row (handling process; 0 for plain paths).
    scheme : str
        Rolling discretisation ("trapezoid" or "paper").
    grasp_angle : float
        Grasp angle of a handling process (rad; NaN otherwise).
    status : str
        "ok", or why the path stopped early (``solve_path(..., on_failure="truncate")``).
    """

    theta: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta_obj: np.ndarray
    d: np.ndarray
    s: np.ndarray
    multipliers: np.ndarray
    energy: np.ndarray
    theta_p: np.ndarray
    constraint_residual: np.ndarray
    kkt_residual: np.ndarray
    reduced_hessian: np.ndarray
    iterations: np.ndarray
    degenerate: np.ndarray
    base_violation: np.ndarray
    op: np.ndarray
    scheme: str = "trapezoid"
    grasp_angle: float = field(default=float("nan"))
    status: str = "ok"

    def __len__(self) -> int:
        return self.theta.shape[0]

    @property
    def n_base_violation(self) -> int:
        """Number of increments (rows) at which either contact passes the fingertip base."""
        return int(np.count_nonzero(self.base_violation.any(axis=1)))

    @property
    def is_minimum(self) -> np.ndarray:
        """(N,) bool: the reduced Hessian is positive (strict local energy minimum)."""
        return self.reduced_hessian > 0.0

    @property
    def pose(self) -> np.ndarray:
        """(N, 3) object poses (x, y, theta_obj) in m, m, rad."""
        return np.column_stack([self.x, self.y, self.theta_obj])

    def state(self, k: int = -1) -> QuasiStaticState:
        """The configuration of row ``k`` (usable as ``state0`` of a continuation)."""
        return QuasiStaticState(
            theta=self.theta[k].copy(),
            x=float(self.x[k]),
            y=float(self.y[k]),
            theta_obj=float(self.theta_obj[k]),
            d=self.d[k].copy(),
            s=self.s[k].copy(),
        )

    @property
    def final(self) -> QuasiStaticState:
        """The configuration of the last row."""
        return self.state(-1)

    def end_of(self, op: int, occurrence: int = 0) -> int:
        """Row index of the last sample of the ``occurrence``-th contiguous run of ``op``."""
        idx = np.flatnonzero(self.op == op)
        if idx.size == 0:
            raise ValueError(f"op {op} does not occur in this path")
        runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
        if not -len(runs) <= occurrence < len(runs):
            raise ValueError(f"op {op} occurs {len(runs)} times (occurrence={occurrence})")
        return int(runs[occurrence][-1])


def resolve_params(params: HandParams | None) -> HandParams:
    """``params``, or Table 4.1 (``load_hand_params("paper_ch4")``) when None; type-checked."""
    if params is None:
        return load_hand_params("paper_ch4")
    if not isinstance(params, HandParams):
        raise ValueError(f"params must be a HandParams (got {type(params).__name__})")
    return params


def _pack(params: HandParams) -> np.ndarray:
    return np.array(
        [params.L, params.W_fi, params.a, params.W_obj, params.d_fi, params.E], dtype=float
    )


def initial_state(params: HandParams | None = None) -> QuasiStaticState:
    """Symmetric first-touch configuration: theta_1 = theta_2 = theta_t, d = 0, s = 0.

    theta_t is :func:`softhand_env.physics.model.initial_finger_angle` (0 for Tables 4.1/5.1, where
    the parallel fingers touch the object at exactly one point); the object centre is at the
    height of the fingertip centres (GQ_i = 0, so s_i = 0) and theta_obj = 0. This is also the
    chapter-5 dynamic model's initial state.

    Raises
    ------
    ValueError
        If the geometry admits no point-contact state.
    """
    from softhand_env.physics.model import initial_finger_angle

    p = resolve_params(params)
    t = initial_finger_angle(p)
    oy = p.L * math.cos(t) - p.d_fi * math.sin(t)
    return QuasiStaticState(
        theta=np.array([t, t]), x=0.0, y=oy, theta_obj=0.0, d=np.zeros(2), s=np.zeros(2)
    )


def _check_theta_path(theta_path: object, name: str = "theta_path") -> np.ndarray:
    try:
        th = np.asarray(theta_path, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape (N, 2) (rad)") from None
    if th.ndim != 2 or th.shape[1] != 2 or th.shape[0] < 1:
        raise ValueError(f"{name} must have shape (N, 2) with N >= 1 (got {th.shape})")
    if not np.all(np.isfinite(th)):
        bad = int(np.flatnonzero(~np.isfinite(th).all(axis=1))[0])
        raise ValueError(f"{name} has a non-finite finger angle at row {bad}")
    if np.any(np.abs(th) >= math.pi / 2):
        raise ValueError(f"{name} has a finger angle with |theta| >= pi/2 rad")
    return np.ascontiguousarray(th)


def _state_vectors(state: QuasiStaticState) -> tuple[np.ndarray, ...]:
    if not isinstance(state, QuasiStaticState):
        raise ValueError(f"state0 must be a QuasiStaticState (got {type(state).__name__})")
    th = np.asarray(state.theta, dtype=float)
    d = np.asarray(state.d, dtype=float)
    s = np.asarray(state.s, dtype=float)
    if th.shape != (2,) or d.shape != (2,) or s.shape != (2,):
        raise ValueError("state0: theta, d and s must each have shape (2,)")
    z = np.array([state.x, state.y, state.theta_obj, d[0], d[1]], dtype=float)
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(th)) and np.all(np.isfinite(s))):
        raise ValueError("state0 has non-finite entries")
    return th, z, s


def solve_path(
    theta_path: np.ndarray,
    params: HandParams | None = None,
    state0: QuasiStaticState | None = None,
    *,
    scheme: str = "trapezoid",
    max_step: float = math.radians(0.5),
    max_iter: int = 30,
    on_failure: str = "raise",
) -> QuasiStaticPath:
    """Quasi-static LMEE states along a path of finger angles.

    Parameters
    ----------
    theta_path : array_like, shape (N, 2)
        Finger angles (theta_1, theta_2) in rad at each increment. Row 0 must equal the finger
        angles of ``state0``; consecutive rows must differ by at most ``max_step`` per finger
        (the rolling sums are only accurate for small increments; use :func:`linear_path`).
    params : HandParams, optional
        Hand parameters (default ``load_hand_params("paper_ch4")``). Uses L, W_fi, a, W_obj,
        d_fi, E.
    state0 : QuasiStaticState, optional
        Start configuration (default :func:`initial_state`). It must satisfy the normal
        constraints and GQ_i = s_i to 1e-9 m.
    scheme : {"trapezoid", "paper"}
        Rolling history sums: trapezoidal (default) or backward Euler as in Eq 4.10.
    max_step : float
        Largest allowed increment per finger (rad).
    max_iter : int
        Newton iterations per increment.
    on_failure : {"raise", "truncate"}
        What to do when an increment cannot be solved: raise (``ValueError`` for an invalid
        path, ``RuntimeError`` for a Newton failure) or return the rows solved before it
        with the reason in :attr:`QuasiStaticPath.status`.

    Returns
    -------
    QuasiStaticPath

    Raises
    ------
    ValueError
        Bad shapes or non-finite angles (message names the argument), a path that opens the
        fingers beyond contact (d_1 + d_2 < 0) or compresses a fingertip to d_i >= a.
    """
    p = resolve_params(params)
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {tuple(SCHEMES)} (got {scheme!r})")
    if on_failure not in ("raise", "truncate"):
        raise ValueError(f"on_failure must be 'raise' or 'truncate' (got {on_failure!r})")
    th = _check_theta_path(theta_path)
    if not (isinstance(max_step, (int, float)) and math.isfinite(max_step) and max_step > 0):
        raise ValueError(f"max_step must be a positive finite float (rad) (got {max_step!r})")
    st = initial_state(p) if state0 is None else state0
    th0, z0, s0 = _state_vectors(st)
    if not np.allclose(th[0], th0, rtol=0.0, atol=1e-12):
        raise ValueError(
            f"theta_path[0] = {th[0].tolist()} must equal state0.theta = {th0.tolist()} (rad)"
        )
    if th.shape[0] > 1:
        big = np.max(np.abs(np.diff(th, axis=0)))
        if big > max_step * (1 + 1e-12):
            raise ValueError(
                f"theta_path increments must be <= max_step = {max_step:.4g} rad per finger "
                f"(largest is {big:.4g} rad); resample it with linear_path"
            )
    prm = _pack(p)
    N = th.shape[0]
    out_z = np.zeros((N, 5))
    out_s = np.zeros((N, 2))
    out_lam = np.zeros((N, 4))
    out_P = np.zeros(N)
    out_res = np.zeros(N)
    out_kkt = np.zeros(N)
    out_hred = np.zeros(N)
    out_iter = np.zeros(N, dtype=np.int64)
    out_deg = np.zeros(N, dtype=np.bool_)
    # row 0 is checked with a trapezoid "increment" of zero length: residual = N_i, GQ_i - s_i
    status, last = _solve_path_kernel(
        th, z0, s0, prm, SCHEMES[scheme], int(max_iter), 1e-14, 1e-11, out_z, out_s, out_lam,
        out_P, out_res, out_kkt, out_hred, out_iter, out_deg,
    )
    if out_res[0] > 1e-9:
        raise ValueError(
            f"state0 violates the constraints by {out_res[0]:.3g} m (needs <= 1e-9 m)"
        )
    msg = ""
    n = last + 1
    if status == _OPENED:
        D = out_z[last, 3] + out_z[last, 4]
        msg = (f"theta_path opens the fingers beyond contact at row {last} "
               f"(theta = {th[last].tolist()} rad, d_1 + d_2 = {D:.3g} m < 0)")
        n = last
    elif status == _OVERCOMPRESSED:
        msg = (f"theta_path compresses a fingertip to d >= a at row {last} "
               f"(theta = {th[last].tolist()} rad, d = {out_z[last, 3:].tolist()} m)")
        n = last
    elif status == _NONFINITE:
        msg = f"the quasi-static solution became non-finite at row {last + 1}"
    elif status == _NOT_CONVERGED:
        msg = (f"Newton did not converge at row {last} (theta = {th[last].tolist()} rad, "
               f"residual {out_res[last]:.3g} m)")
        n = last
    if not msg and n > 0:
        bad = np.flatnonzero(np.abs(th[:n, 0] - out_z[:n, 2]) >= 0.5 * math.pi)
        bad = np.union1d(bad, np.flatnonzero(np.abs(th[:n, 1] + out_z[:n, 2]) >= 0.5 * math.pi))
        if bad.size:
            status, n = _NONFINITE, int(bad[0])
            msg = f"contact angle |theta_p| >= 90 deg at row {n}: outside the model"
    if msg and on_failure == "raise":
        raise (RuntimeError if status == _NOT_CONVERGED else ValueError)(msg)
    return _make_path(th[:n], out_z[:n], out_s[:n], out_lam[:n], out_P[:n], out_res[:n],
                      out_kkt[:n], out_hred[:n], out_iter[:n], out_deg[:n], p, scheme,
                      status=msg or "ok")


def _base_flags(d: np.ndarray, theta_p: np.ndarray, a: float) -> np.ndarray:
    """(N, 2) True where the contact circle passes the fingertip base.

    Uses :func:`~softhand_env.physics.contact.contact_within_base`; compressions of degenerate
    rows can be round-off negatives (|d| < D_DEGENERATE) and are clipped to 0 for the check.
    """
    from softhand_env.physics.contact import contact_within_base

    return ~np.asarray(contact_within_base(np.maximum(d, 0.0), theta_p, a), dtype=bool)


def _make_path(th, z, s, lam, P, res, kkt, hred, iters, deg, p, scheme, status="ok"):
    theta_p = np.column_stack([th[:, 0] - z[:, 2], th[:, 1] + z[:, 2]])
    d = z[:, 3:5].copy()
    return QuasiStaticPath(
        theta=th.copy(),
        x=z[:, 0].copy(),
        y=z[:, 1].copy(),
        theta_obj=z[:, 2].copy(),
        d=d,
        s=s.copy(),
        multipliers=lam.copy(),
        energy=P.copy(),
        theta_p=theta_p,
        constraint_residual=res.copy(),
        kkt_residual=kkt.copy(),
        reduced_hessian=hred.copy(),
        iterations=iters.copy(),
        degenerate=deg.copy(),
        base_violation=_base_flags(d, theta_p, p.a),
        op=np.zeros(th.shape[0], dtype=np.int64),
        scheme=scheme,
        status=status,
    )


def linear_path(start: ArrayLike, end: ArrayLike, step: float = DEFAULT_STEP) -> np.ndarray:
    """Straight finger-angle path from ``start`` to ``end`` (both (2,), rad), ends included.

    The number of increments is ceil(max|end - start| / step); returns shape (n + 1, 2).
    """
    a0 = np.asarray(start, dtype=float)
    a1 = np.asarray(end, dtype=float)
    if a0.shape != (2,) or a1.shape != (2,):
        raise ValueError("start and end must have shape (2,) (rad)")
    if not (np.all(np.isfinite(a0)) and np.all(np.isfinite(a1))):
        raise ValueError("start and end must be finite (rad)")
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be a positive finite float (rad) (got {step!r})")
    n = max(1, math.ceil(np.max(np.abs(a1 - a0)) / step - 1e-9))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    out = a0 + t * (a1 - a0)
    out[-1] = a1
    return out


def resample(theta: np.ndarray, step: float = DEFAULT_STEP) -> tuple[np.ndarray, np.ndarray]:
    """Insert samples so that consecutive finger angles differ by at most ``step``.

    Use it to run :func:`solve_path` along a recorded finger trajectory, e.g. the actual
    (not commanded) angles of the chapter-5 dynamic model, and compare at the recorded times.

    Parameters
    ----------
    theta : array_like, shape (M, 2)
        Finger angles (rad).
    step : float
        Largest increment per finger (rad).

    Returns
    -------
    path : ndarray, shape (N, 2)
        Piecewise-linear resampling (N >= M), rad.
    index : ndarray of int, shape (M,)
        ``path[index[k]] == theta[k]``.
    """
    th = _check_theta_path(theta, "theta")
    segs = [linear_path(a0, a1, step)[1:] for a0, a1 in zip(th[:-1], th[1:], strict=True)]
    counts = np.array([0] + [s.shape[0] for s in segs], dtype=np.int64)
    return np.vstack([th[:1]] + segs), np.cumsum(counts)
