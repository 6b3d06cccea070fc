"""Friction the rolling contacts need, from the contact impulses of a control step.

The chapter-5 model enforces pure rolling (the non-holonomic constraints) and a bilateral
normal contact (the holonomic constraints) with Lagrange multipliers: lambda_H,i is the
normal force of fingertip i on the object (N, > 0 pushes), lambda_N,i the tangential force
along the object's face (N). Nothing in the model limits them, so a motion may need a
tangential force no real fingertip can supply (Coulomb: |F_t| <= mu F_n) or a normal pull.
This module judges a control step by its *impulses*

    J_n,i = integral of lambda_H,i dt,   J_t,i = integral of lambda_N,i dt   (N s)

over the step, as the compiled kernel accumulates them (:mod:`softhand_env.physics.kernel`,
``diag[3:7]``), and calls the step's friction ratio

    r_i = |J_t,i| / J_n,i          (dimensionless; inf where J_n,i <= 0).

Why impulses over the step, not the largest instantaneous force ratio: after a set-point
jump the multipliers go through a transient of a few 0.1 ms substeps in which the
deformation coordinates (which carry the inertia M_deform) are accelerated; the
instantaneous ratio |lambda_N| / lambda_H then peaks far above its settled value (measured:
~20 for one substep) although the momentum it transfers is tiny. Whether a contact slips
depends on the momentum the contact must transfer, not on a force spike far shorter than
any slip could develop in (a stick-slip transition of an elastomer contact takes
milliseconds); time-stepping contact models impose Coulomb's law on the impulse of a step
for the same reason (Stewart and Trinkle 1996, Anitescu and Potra 1997). Over a step the
ratio of impulses is the ratio of the mean forces, so at rest it is the static ratio
|F_t| / F_n exactly. A control step (20 ms in the environments) is far longer than the
transient, so the transient is averaged in with its true weight (its share of the momentum).
With the environments' ``slip_window_ms`` the same check applies to fixed windows of physical
time instead of control steps (:mod:`softhand_env.envs.windows`), so its strictness does not
depend on the agent's control period.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)


def _split(impulse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    imp = np.asarray(impulse, dtype=np.float64)
    if imp.shape[-1:] != (4,):
        raise ValueError(f"impulse must have shape (..., 4) (got {imp.shape})")
    return imp[..., 0:2], imp[..., 2:4]


def friction_ratio(impulse: np.ndarray) -> np.ndarray:
    """Friction ratio |J_t,i| / J_n,i per finger.

    Parameters
    ----------
    impulse : array_like, shape (..., 4)
        Contact impulses (J_n1, J_n2, J_t1, J_t2) in N s, as in ``diag[..., 3:7]`` of the
        kernel or :attr:`softhand_env.physics.StepStatus.impulse`.

    Returns
    -------
    ndarray, shape (..., 2)
        Dimensionless ratio; ``inf`` where J_n,i <= 0 (a contact that pulls or transfers no
        normal momentum cannot hold any tangential one).
    """
    jn, jt = _split(impulse)
    out = np.full(jn.shape, np.inf)
    np.divide(np.abs(jt), jn, out=out, where=jn > 0.0)
    return out


def tension(impulse: np.ndarray) -> np.ndarray:
    """True per finger whose normal impulse is negative (the bilateral contact pulled).

    ``impulse`` as in :func:`friction_ratio`; returns bool, shape (..., 2).
    """
    jn, _ = _split(impulse)
    return jn < 0.0


def slipping(impulse: np.ndarray, mu: float | np.ndarray) -> np.ndarray:
    """True per finger whose friction ratio exceeds the friction coefficient ``mu``.

    ``impulse`` as in :func:`friction_ratio`; ``mu`` (dimensionless, > 0) broadcasts against
    the leading axes (e.g. shape (N, 1) for one coefficient per system). A finger in tension
    also counts as slipping (its ratio is inf). Returns bool, shape (..., 2).
    """
    return friction_ratio(impulse) > np.asarray(mu, dtype=np.float64)


@njit(cache=True)
def check_contact(impulse, mu, failed, skip, impulse_out, ratio_out, tension_out, bad_out):
    """Contact check of one control step for N systems, in place (compiled; the arithmetic of
    :func:`friction_ratio` and :func:`tension`, element by element, so the results are equal).

    Parameters
    ----------
    impulse : ndarray, shape (N, 4)
        (J_n1, J_n2, J_t1, J_t2) of the step (N s); non-finite entries (a diverged, rolled-back
        step) are read as 0.
    mu : ndarray, shape (N,)
        Friction coefficient per system.
    failed, skip : ndarray of bool, shape (N,)
        Systems that failed otherwise this step, or were not stepped: never flagged here.
    impulse_out : ndarray, shape (N, 4), output
        The impulses as read (non-finite -> 0).
    ratio_out : ndarray, shape (N, 2), output
        |J_t| / J_n per finger (inf where J_n <= 0).
    tension_out : ndarray of bool, shape (N, 2), output
        J_n < 0 per finger.
    bad_out : ndarray of bool, shape (N,), output
        Systems whose contact pulled or needed more friction than their ``mu``.
    """
    for s in range(impulse.shape[0]):
        bad = False
        for j in range(4):
            v = impulse[s, j]
            impulse_out[s, j] = v if np.isfinite(v) else 0.0
        for f in range(2):
            jn = impulse_out[s, f]
            jt = impulse_out[s, 2 + f]
            r = abs(jt) / jn if jn > 0.0 else np.inf
            ratio_out[s, f] = r
            tension_out[s, f] = jn < 0.0
            if r > mu[s]:
                bad = True
        bad_out[s] = bad and not failed[s] and not skip[s]


__all__ = ["check_contact", "friction_ratio", "slipping", "tension"]
