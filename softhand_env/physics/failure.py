"""Failure classification of a hand after a control step: the single implementation.

:func:`classify` turns what the kernel reports for each hand (status flags, the step's largest
residuals, the state) into the physical failures the environments terminate on, in one
compiled pass over N hands:

- ``nonfinite_state``: NaN/inf in the state; the hand is rolled back to the state before the
  step (observations and info stay finite) and its non-finite residuals read +inf.
- ``constraint_violation``: the step's largest |C^H| exceeded ``ch_limit``.
- ``overcompressed``: a d_n >= ``dn_limit``.
- ``grasp_lost``: a d_n <= 0 (the bilateral contact would pull).
- ``contact_past_base``: a contact circle reached past its fingertip base by more than the
  allowed tolerance (:func:`softhand_env.physics.kernel.past_base` with ``limit = base_limit``).

If several apply, the first of :data:`REASONS` is reported. A hand is *grasped* when both
d_n > 0 and its state did not diverge.
"""

from __future__ import annotations

import math

from numba import njit

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.kernel import (
    FLAG_BASE,
    FLAG_CONSTRAINT,
    FLAG_LOST,
    FLAG_NONFINITE,
    FLAG_OVERCOMPRESSED,
    FLAG_SKIP,
    past_base,
)
from softhand_env.physics.model import DN_1, NY, P_A

#: Termination reasons, highest priority first; :func:`classify` writes index + 1 (0: none).
REASONS = (
    "nonfinite_state",
    "constraint_violation",
    "overcompressed",
    "grasp_lost",
    "contact_past_base",
)
_DIVERGED = FLAG_NONFINITE | FLAG_CONSTRAINT


@njit(cache=True, inline="always")
def holds(dn1, dn2):
    """The grasp rule: both fingertips compressed (d_n1, d_n2 > 0, m). A step's hand is
    grasped when this holds and the step did not diverge (:func:`classify`); a start state
    when it holds."""
    return dn1 > 0.0 and dn2 > 0.0


@njit(cache=True)
def classify(FLAGS, Y, Y_PREV, PRM, DIAG, ch_limit, dn_limit, base_limit, FAILED, GRASPED,
             REASON):
    """Classify N hands after a step, in place.

    Parameters
    ----------
    FLAGS : ndarray of int64, shape (N,), modified
        Kernel flags of the step; ``FLAG_CONSTRAINT`` is added where ``DIAG[:, 0] > ch_limit``
        (the kernel checks the bound only for steps it completes). Hands carrying
        ``FLAG_SKIP`` are left alone (not failed, not grasped, flags 0).
    Y : ndarray, shape (N, 20), modified
        States after the step; non-finite rows are replaced by ``Y_PREV``'s.
    Y_PREV : ndarray, shape (N, 20)
        States before the step.
    PRM : ndarray, shape (N, N_PARAMS)
        Packed parameters (fingertip radius a).
    DIAG : ndarray, shape (N, >= 2), modified
        max |C^H| (m), max |C^N| (m/s) of the step; non-finite entries of failed hands
        become +inf.
    ch_limit, dn_limit : float
        Bounds on |C^H| (m) and d_n (m).
    base_limit : float
        Allowed reach past the fingertip base (1 = none; inf switches the check off).
    FAILED, GRASPED : ndarray of bool, shape (N,), output
    REASON : ndarray of int64, shape (N,), output
        0 (running) or 1 + the index in :data:`REASONS` of the failure reported.
    """
    for s in range(FLAGS.shape[0]):
        f = FLAGS[s]
        if f & FLAG_SKIP:
            FLAGS[s] = 0
            FAILED[s] = False
            GRASPED[s] = False
            REASON[s] = 0
            continue
        if DIAG[s, 0] > ch_limit:  # NaN compares False: NaN states carry their own flag
            f |= FLAG_CONSTRAINT
        if f & FLAG_NONFINITE:
            for j in range(NY):
                Y[s, j] = Y_PREV[s, j]
        dn1 = Y[s, DN_1]
        dn2 = Y[s, DN_1 + 1]
        diverged = (f & _DIVERGED) != 0
        over = (f & FLAG_OVERCOMPRESSED) != 0 or dn1 >= dn_limit or dn2 >= dn_limit
        lost = (f & FLAG_LOST) != 0 or dn1 <= 0.0 or dn2 <= 0.0
        base = (f & FLAG_BASE) != 0
        if base and base_limit > 1.0:
            base = past_base(Y[s], PRM[s, P_A], base_limit)
        failed = diverged or over or lost or base
        if failed:
            for j in range(2):
                if not (DIAG[s, j] - DIAG[s, j] == 0.0):
                    DIAG[s, j] = math.inf
        FLAGS[s] = f
        FAILED[s] = failed
        GRASPED[s] = holds(dn1, dn2) and not diverged
        if f & FLAG_NONFINITE:
            REASON[s] = 1
        elif f & FLAG_CONSTRAINT:
            REASON[s] = 2
        elif over:
            REASON[s] = 3
        elif lost:
            REASON[s] = 4
        elif base:
            REASON[s] = 5
        else:
            REASON[s] = 0

