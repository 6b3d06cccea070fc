"""Actions: map the agent's action to the pair of finger-angle set-points the PID tracks.

=====================================  ==========================================================
mode                                   set-point u_t (rad) from action a
=====================================  ==========================================================
``"delta"`` (default)                  u_t = clip(u_{t-1} + clip(a, -1, 1) * max_delta, range)
``"absolute"``                         u_t = mid + clip(a, -1, 1) * half_width of the joint range
``"absolute"``, ``normalize_action``   u_t = clip(a, range): the action IS the set-point pair in
=False                                 rad and the action space is the joint range in rad
=====================================  ==========================================================

Out-of-range actions are clipped (as above); NaN or inf raise ``ValueError``. The same compiled
code maps one action (shape (2,)) or a batch (shape (N, 2)) and computes the control cost
|u_t - u_{t-1}|^2 / max_delta^2 of the reward.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from numba import njit

from softhand_env.envs.options import KEYWORDS, check_keyword
from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)

ACTION_MODES = KEYWORDS["action_mode"].choices


class ActionMap:
    """Action space and action -> set-point mapping (see module doc).

    Parameters
    ----------
    action_mode : str
        ``"delta"`` or ``"absolute"``.
    normalize_action : bool
        If False (only with ``"absolute"``), the action space is the joint range in rad.
    max_delta_deg : float
        Largest set-point change per control step in ``"delta"`` mode (deg); also the unit of
        the control cost.
    joint_range_deg : (float, float)
        Set-point limits (deg), low < high.
    """

    def __init__(
        self,
        action_mode: str,
        normalize_action: bool,
        max_delta_deg: float,
        joint_range_deg: Sequence[float],
    ):
        check_keyword("action_mode", action_mode)
        if not normalize_action and action_mode != "absolute":
            raise ValueError('normalize_action=False requires action_mode="absolute"')
        check_keyword("max_delta_deg", max_delta_deg)
        check_keyword("joint_range_deg", joint_range_deg)
        lo, hi = (float(v) for v in joint_range_deg)
        if not lo < hi:
            raise ValueError(
                f"joint_range_deg must be (low, high) with low < high, each in "
                f"{KEYWORDS['joint_range_deg'].range_text} (got {tuple(joint_range_deg)!r})"
            )
        self.mode = action_mode
        self.normalize = bool(normalize_action)
        self.delta = action_mode == "delta"
        self.max_delta = math.radians(max_delta_deg)
        self.low = math.radians(lo)
        self.high = math.radians(hi)
        self._mid = 0.5 * (self.low + self.high)
        self._half = 0.5 * (self.high - self.low)
        self._kind = 0 if self.delta else (1 if self.normalize else 2)

    def space(self) -> spaces.Box:
        """[-1, 1]^2, or the joint range in rad when not normalised (float32)."""
        if self.normalize:
            return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        return spaces.Box(self.low, self.high, shape=(2,), dtype=np.float32)

    def map_constants(self) -> tuple[int, float, float, float, float, float]:
        """The constants of the compiled set-point map (``_map_setpoints``): the mode code
        (0 delta, 1 absolute normalised, 2 absolute in rad), ``max_delta``, the joint range's
        middle and half width, ``low`` and ``high`` (rad)."""
        return self._kind, self.max_delta, self._mid, self._half, self.low, self.high

    def setpoints(self, action: np.ndarray, previous: np.ndarray) -> tuple[np.ndarray, Any]:
        """New set-points (rad) and the control cost |u - previous|^2 / max_delta^2.

        Parameters
        ----------
        action : array_like, shape (2,) or (N, 2)
        previous : ndarray of float64, shape (2,) or (N, 2)
            Set-points of the previous step (rad).

        Returns
        -------
        u : ndarray of float64, shape of ``previous``
        ctrl : float or ndarray (N,)

        Raises
        ------
        ValueError
            Wrong shape, or NaN/inf in the action.
        """
        a = np.asarray(action)
        if a.dtype != np.float32 and a.dtype != np.float64:
            a = a.astype(np.float64)
        if a.shape != previous.shape:
            raise ValueError(f"action must have shape {previous.shape} (got {a.shape})")
        one = previous.ndim == 1
        a2, prev2 = (a.reshape(1, 2), previous.reshape(1, 2)) if one else (a, previous)
        u = np.empty(prev2.shape)
        ctrl = np.empty(prev2.shape[0])
        ok = _map_setpoints(a2, prev2, self._kind, self.max_delta, self._mid, self._half,
                            self.low, self.high, u, ctrl)
        if not ok:
            raise ValueError(f"action must be finite (got {a.tolist()})")
        return (u[0], float(ctrl[0])) if one else (u, ctrl)


def action_array(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as a float32/float64 array of ``shape``, or an error naming ``action``.

    Accepted: real numeric arrays or sequences (bool, int, float kinds), and objects NumPy reads
    as one (a CPU torch tensor is converted; one that requires grad or lives on a GPU is a
    ``TypeError``). Raises ``TypeError``
    for anything else (complex, strings, dates, objects, masked arrays, dicts, ints too large
    for a float) and ``ValueError`` for a wrong shape; NaN/inf are rejected by
    :meth:`ActionMap.setpoints`.
    """
    if isinstance(action, np.ma.MaskedArray):
        raise TypeError("action must be a plain array of real numbers (got a masked array)")
    try:
        # a CPU tensor (torch, jax, ...) converts through __array__; one that requires grad or
        # lives on a GPU raises RuntimeError/TypeError there: both are the caller's to convert
        a = np.asarray(action)
    except RuntimeError:
        raise TypeError(
            f"action must be an array of real numbers; a {type(action).__name__} that cannot "
            "be read as one (e.g. a tensor that requires grad or lives on a GPU: pass "
            "tensor.detach().cpu().numpy())"
        ) from None
    except (TypeError, ValueError, OverflowError):
        raise TypeError(
            f"action must be an array of real numbers (got {type(action).__name__})"
        ) from None
    if a.dtype.kind not in "biuf":
        raise TypeError(
            f"action must hold real numbers (bool, int or float), got dtype {a.dtype} "
            f"({type(action).__name__})"
        )
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape} (got {a.shape})")
    if a.dtype != np.float32 and a.dtype != np.float64:
        a = a.astype(np.float64)
    return a


@njit(cache=True)
def _map_setpoints(a, prev, kind, max_delta, mid, half, low, high, u, ctrl):
    """Set-points u (N, 2) and control costs ctrl (N,) for actions a (N, 2) and the previous
    set-points prev (N, 2); False on NaN/inf.

    ``kind``: 0 = delta, 1 = absolute normalised, 2 = absolute in rad (module doc).
    """
    for s in range(a.shape[0]):
        for j in range(2):
            if not math.isfinite(a[s, j]):
                return False
    for s in range(a.shape[0]):
        for j in range(2):
            x = float(a[s, j])
            if kind != 2:
                x = min(max(x, -1.0), 1.0)
                x = prev[s, j] + x * max_delta if kind == 0 else mid + x * half
            u[s, j] = min(max(x, low), high)
        d0 = (u[s, 0] - prev[s, 0]) / max_delta
        d1 = (u[s, 1] - prev[s, 1]) / max_delta
        ctrl[s] = d0 * d0 + d1 * d1
    return True


@njit(cache=True)
def delay_setpoints(cmd, sent, latency, applied):
    """Set-point latency: record the commanded set-points cmd (N, 2) as the newest of sent
    (N, K, 2) (the last K commands, newest first; K > 0) and write into applied (N, 2) those
    commanded latency[s] (int (N,), 0..K) steps ago, cmd itself for 0."""
    for s in range(cmd.shape[0]):
        lag = latency[s]
        for j in range(2):
            applied[s, j] = cmd[s, j] if lag == 0 else sent[s, lag - 1, j]
        for k in range(sent.shape[1] - 1, 0, -1):
            sent[s, k, 0] = sent[s, k - 1, 0]
            sent[s, k, 1] = sent[s, k - 1, 1]
        sent[s, 0, 0] = cmd[s, 0]
        sent[s, 0, 1] = cmd[s, 1]
