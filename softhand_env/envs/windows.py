"""Slip and tension judged on windows of physical time, independent of the control period.

With ``slip_window_ms`` set, the contact check of :mod:`softhand_env.physics.friction` is not
applied to the impulses of a control step but to those of consecutive windows of ``window``
RK4 substeps, tiled from the start of the episode (the end of the grasp phase; they restart
at every reset). A control step longer than a window is integrated window by window (one
kernel call per piece, cut at the window ends: the substeps, hence the states, are those of
one call); a shorter step adds its impulses to the current window. A window is judged when it
ends, in the step in which it ends: its friction ratio |J_t| / J_n per finger, tension where
J_n < 0, and slip where the ratio exceeds the episode's mu. With ``stop`` (the environments'
``terminate_on_slip``) a hand whose window slipped or pulled is not integrated past that
window's end, so the episode ends at the same physical time whatever the control period.

A hand that fails physically (:mod:`softhand_env.physics.failure`) in a piece stops there;
its unfinished window is not judged. A non-finite state is rolled back to the start of its
piece (:meth:`~softhand_env.physics.HandPhysics.step`).

Every hand is cut at its own window ends only (hands with other window phases are stepped in
separate calls), so N environments in one batch give bit for bit what N single ones give.

A set-point ramp (``setpoint_ramp_ms``) cuts the pieces at its stair ends too: the first
``ramp`` substeps of a control step are integrated stair by stair, stair k (0-based, of
``stair`` substeps) holding the set-points before the step plus (k + 1) / K of the step's
change (K = ``ramp / stair``), the rest of the step at the new set-points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)
from softhand_env.physics.hand import HandPhysics


class WindowedStep(NamedTuple):
    """Outcome of one control step judged on windows (leading axis N hands).

    Attributes
    ----------
    flags : ndarray of int64, shape (N,)
        Kernel status flags of the step's pieces, OR-ed.
    constraint_error : ndarray, shape (N, 2)
        Largest |C^H| (m) and |C^N| (m/s) over the states of the step.
    failed, grasped : ndarray of bool, shape (N,)
        Physical failure and grasp after the last piece a hand ran (as
        :class:`~softhand_env.physics.StepStatus`).
    reason_code : ndarray of int64, shape (N,)
        Physical failure code (0: none; names in
        :data:`~softhand_env.physics.hand.REASON_NAMES`).
    impulse : ndarray, shape (N, 4)
        Contact impulses (J_n1, J_n2, J_t1, J_t2; N s) over the step (non-finite read as 0).
    friction_ratio : ndarray, shape (N, 2)
        Largest |J_t| / J_n per finger over the windows that ended in the step (inf where a
        window's J_n <= 0; 0 where no window ended).
    tension : ndarray of bool, shape (N, 2)
        A window that ended in the step had J_n < 0.
    contact : ndarray of bool, shape (N,)
        A window that ended in the step slipped (ratio above mu) or pulled.
    """

    flags: np.ndarray
    constraint_error: np.ndarray
    failed: np.ndarray
    grasped: np.ndarray
    reason_code: np.ndarray
    impulse: np.ndarray
    friction_ratio: np.ndarray
    tension: np.ndarray
    contact: np.ndarray


@njit(cache=True)
def _account(m, st_flags, st_error, st_impulse, st_substeps, mu, stop, window, left,
             win_impulse, failed, active, done, flags, error, step_impulse, ratio, tension,
             contact):
    """Book one kernel piece of the hands ``m`` (bool (N,)), in place: their flags, residual
    maxima, impulses (non-finite read as 0) and substeps; judge each window that ended with
    it (the arithmetic of :func:`softhand_env.physics.friction.check_contact`: ratio
    |J_t| / J_n, inf where J_n <= 0; tension J_n < 0; bad if tension or ratio > mu) and start
    the next one; deactivate hands that failed, or (``stop``) whose window was bad."""
    for s in range(m.shape[0]):
        if not m[s]:
            continue
        flags[s] |= st_flags[s]
        for j in range(2):
            error[s, j] = max(error[s, j], st_error[s, j])
        for j in range(4):
            v = st_impulse[s, j]
            v = v if np.isfinite(v) else 0.0
            step_impulse[s, j] += v
            win_impulse[s, j] += v
        done[s] += st_substeps[s]
        left[s] -= st_substeps[s]
        if failed[s]:
            active[s] = False
            continue
        if left[s] > 0:
            continue
        bad = False
        for f in range(2):
            jn = win_impulse[s, f]
            r = abs(win_impulse[s, 2 + f]) / jn if jn > 0.0 else np.inf
            ratio[s, f] = max(ratio[s, f], r)
            if jn < 0.0:
                tension[s, f] = True
            if r > mu[s]:
                bad = True
        if bad:
            contact[s] = True
            if stop:
                active[s] = False
        for j in range(4):
            win_impulse[s, j] = 0.0
        left[s] = window


class SlipWindows:
    """The current slip window of each of N hands (see the module doc).

    Parameters
    ----------
    num_hands : int
    window : int
        Window length in RK4 substeps (>= 1).

    Attributes
    ----------
    left : ndarray of int64, shape (N,)
        Substeps left in each hand's current window.
    impulse : ndarray, shape (N, 4)
        Contact impulses (N s) accumulated in each hand's current window.
    """

    def __init__(self, num_hands: int, window: int):
        if window < 1:
            raise ValueError(f"window must be >= 1 substep (got {window!r})")
        self.window = int(window)
        self.left = np.full(num_hands, self.window, dtype=np.int64)
        self.impulse = np.zeros((num_hands, 4))

    def restart(self, i: int | np.ndarray) -> None:
        """Start a fresh window for hand ``i`` (an index or int array of them; at a reset)."""
        self.left[i] = self.window
        self.impulse[i] = 0.0

    def step(
        self,
        physics: HandPhysics,
        setpoint: np.ndarray,
        n_substeps: int,
        mu: np.ndarray,
        stop: bool,
        skip: np.ndarray | None = None,
        ramp: int = 0,
        stair: int = 0,
    ) -> WindowedStep:
        """One control step of ``n_substeps`` substeps of every hand of ``physics`` (N, with
        the hand axis) holding ``setpoint`` (N, 2) (rad), judged on the windows.

        ``mu`` (N,) is each hand's friction coefficient; ``stop``: a hand whose window slipped
        or pulled stops at that window's end; ``skip`` (N,) bool: hands left untouched;
        ``ramp`` > 0: the set-points move from the physics' current ones to ``setpoint`` over
        the first ``ramp`` substeps in stairs of ``stair`` substeps (see the module doc).
        """
        n = physics.num_hands
        start = physics.step_arrays()[1].copy() if ramp > 0 else setpoint
        active = np.ones(n, dtype=bool) if skip is None else ~np.asarray(skip, dtype=bool)
        done = np.zeros(n, dtype=np.int64)
        flags = np.zeros(n, dtype=np.int64)
        error = np.zeros((n, 2))
        failed = np.zeros(n, dtype=bool)
        grasped = np.zeros(n, dtype=bool)
        reason = np.zeros(n, dtype=np.int64)
        step_impulse = np.zeros((n, 4))
        ratio = np.zeros((n, 2))
        tension = np.zeros((n, 2), dtype=bool)
        contact = np.zeros(n, dtype=bool)
        while True:
            piece = np.minimum(n_substeps - done, self.left)
            target = setpoint
            if ramp > 0:  # cut at the stair ends; a stair's share of the change
                ramping = done < ramp
                piece = np.where(ramping, np.minimum(piece, stair - done % stair), piece)
                share = np.minimum((done // stair + 1) * stair / ramp, 1.0)
                target = np.where((share < 1.0)[:, None],
                                  start + (setpoint - start) * share[:, None], setpoint)
            todo = active & (piece > 0)
            if not todo.any():
                break
            length = int(piece[todo].max())
            m = todo & (piece == length)
            st = physics.step(target, length, strict=False, skip=~m).hands
            # every hand in this piece (the usual case): whole rows, no masked copies
            sel: slice | np.ndarray = slice(None) if m.all() else m
            failed[sel] = st.failed[sel]
            grasped[sel] = st.grasped[sel]
            reason[sel] = st.arrays()[4][sel]  # failure codes
            _account(m, st.flags, st.constraint_error, st.impulse, st.substeps, mu, stop,
                     self.window, self.left, self.impulse, failed, active, done, flags, error,
                     step_impulse, ratio, tension, contact)
        return WindowedStep(flags, error, failed, grasped, reason, step_impulse, ratio,
                            tension, contact)


__all__ = ["SlipWindows", "WindowedStep"]
