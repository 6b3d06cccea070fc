"""Plain-NumPy reference of the CSM model: dense KKT solve, Python RK4 loop.

It evaluates the same model terms as the compiled kernel
(:func:`.model.constraint_terms`, :func:`.model.potential_forces`) but
assembles the full 13x13 system of Eq 5.24, solves it with :func:`numpy.linalg.solve` and
integrates with the generic :func:`.integrate.rk_step`. It is slow (a Python call
per stage) and exists to cross-check the kernel's Schur-complement solve and unrolled RK4, and
as the speed baseline of the benchmark.
"""

from __future__ import annotations

import numpy as np

from softhand_env.physics.integrate import integrate_fixed
from softhand_env.physics.model import (
    NQ,
    P_ALPHA,
    P_BETA,
    P_DT,
    P_I1,
    P_I2,
    P_IOBJ,
    P_MDEF,
    P_MOBJ,
    TH_1,
    TH_2,
    constraint_terms,
    pid_torques,
    potential_forces,
)


def mass_matrix(prm: np.ndarray) -> np.ndarray:
    """Diagonal inertia matrix of Eq 5.14, shape (9, 9) (kg, kg m^2)."""
    m, md = prm[P_MOBJ], prm[P_MDEF]
    return np.diag([m, m, prm[P_IOBJ], prm[P_I1], prm[P_I2], md, md, md, md])


def kkt_rhs(t: float, y: np.ndarray, u: np.ndarray, prm: np.ndarray) -> np.ndarray:
    """dy/dt of the state [q, p, z] (20,) by the dense KKT system of Eq 5.24."""
    q, p = y[:NQ], y[NQ : 2 * NQ]
    Phi = np.empty((4, NQ))
    b = np.empty(4)
    C = np.empty(2)
    f = np.empty(NQ)
    constraint_terms(q, p, prm, Phi, b, C)
    potential_forces(q, p, prm, f)
    tau = np.empty(2)
    pid_torques(y, u, prm, tau)
    f[TH_1] += tau[0]
    f[TH_2] += tau[1]
    alpha, beta = prm[P_ALPHA], prm[P_BETA]
    phip = Phi @ p
    gamma = np.concatenate(
        [b[:2] + 2 * alpha * phip[:2] + alpha**2 * C, b[2:] + beta * phip[2:]]
    )
    K = np.zeros((NQ + 4, NQ + 4))
    K[:NQ, :NQ] = mass_matrix(prm)
    K[:NQ, NQ:] = -Phi.T
    K[NQ:, :NQ] = -Phi
    sol = np.linalg.solve(K, np.concatenate([f, gamma]))
    return np.concatenate([p, sol[:NQ], [y[TH_1] - u[0], y[TH_2] - u[1]]])


def advance_reference(y: np.ndarray, u: np.ndarray, prm: np.ndarray, n: int) -> np.ndarray:
    """Integrate ``n`` RK4 substeps of ``prm[P_DT]`` with the NumPy reference; returns y (20,)."""
    return integrate_fixed(kkt_rhs, 0.0, y, prm[P_DT], n, np.asarray(u, float), prm)


__all__ = ["advance_reference", "kkt_rhs", "mass_matrix"]
