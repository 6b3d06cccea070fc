"""Explicit Runge-Kutta integration as plain functions, independent of any physics.

The model is just ``fun(t, y, *args) -> dy/dt`` (as in :mod:`scipy.integrate`); the classic
fourth-order tableau below is the one the compiled kernel (:mod:`.kernel`) unrolls.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

#: Classic RK4 Butcher tableau: nodes c, matrix A (strictly lower), weights b.
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])
RK4_A = np.array(
    [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
)
RK4_B = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0


def rk_step(
    fun: Callable[..., np.ndarray],
    t: float,
    y: np.ndarray,
    h: float,
    *args: Any,
    A: np.ndarray = RK4_A,
    b: np.ndarray = RK4_B,
    c: np.ndarray = RK4_C,
) -> np.ndarray:
    """One explicit Runge-Kutta step (default: classic RK4).

    Parameters
    ----------
    fun : callable
        ``fun(t, y, *args)`` returning dy/dt with the shape of ``y``.
    t : float
        Time at the start of the step (s).
    y : ndarray, shape (n,)
        State at ``t``.
    h : float
        Step size (s).
    *args
        Extra arguments passed to ``fun`` (e.g. control input and parameters).
    A, b, c : ndarray
        Butcher tableau (stages x stages, stages, stages).

    Returns
    -------
    ndarray, shape (n,)
        State at ``t + h``.
    """
    k = np.empty((len(b), *np.shape(y)))
    for s in range(len(b)):
        ys = y + h * np.tensordot(A[s, :s], k[:s], axes=1) if s else y
        k[s] = fun(t + c[s] * h, ys, *args)
    return y + h * np.tensordot(b, k, axes=1)


def integrate_fixed(
    fun: Callable[..., np.ndarray], t0: float, y0: np.ndarray, h: float, n: int, *args: Any
) -> np.ndarray:
    """Apply :func:`rk_step` ``n`` times from ``(t0, y0)``; returns the final state (n,)."""
    y = np.array(y0, dtype=float)
    t = t0
    for _ in range(n):
        y = rk_step(fun, t, y, h, *args)
        t += h
    return y
