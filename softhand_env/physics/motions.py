"""Open-loop runs of set-point sequences through the dynamic model (the paper's §5.5.1).

:func:`run_setpoint_sequence` holds each set-point pair for a fixed duration and records the
state at a fixed interval; :data:`PAPER_MOTIONS_DEG` is the example motion of §5.5.1. The paper
gives no duration for its motions; it is a parameter (default 1 s each).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from softhand_env.physics.hand import HandPhysics
from softhand_env.physics.model import NY, Q_NAMES
from softhand_env.physics.params import HandParams

#: Motions 1-8 of §5.5.1: (theta_1^d, theta_2^d) in degrees, from the parallel initial state.
PAPER_MOTIONS_DEG: tuple[tuple[float, float], ...] = (
    (6.0, 6.0),
    (20.0, -10.0),
    (-2.0, 13.0),
    (-10.0, 20.0),
    (-7.0, 17.0),
    (17.0, -7.0),
    (-15.0, 25.0),
    (5.0, 5.0),
)


@dataclass(frozen=True)
class Trajectory:
    """A recorded run; row k describes the interval ending at ``t[k]``.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Time at the end of each recording interval (s); ``t[0] = 0`` is the initial state.
    y : ndarray, shape (K, 20)
        State [q, p, z] at ``t``.
    setpoint : ndarray, shape (K, 2)
        Set-points (rad) held during the interval ending at ``t`` (row 0: first motion's).
    max_ch, max_cn : ndarray, shape (K,)
        Largest |C^H| (m) and |C^N| (m/s) over the interval (row 0: at the initial state).
    flags : ndarray of int, shape (K,)
        Kernel status flags of the interval.
    motion : ndarray of int, shape (K,)
        Index of the motion (0-based) the row belongs to.
    switch_times : ndarray, shape (M,)
        Start time of each motion (s).
    """

    t: np.ndarray
    y: np.ndarray
    setpoint: np.ndarray
    max_ch: np.ndarray
    max_cn: np.ndarray
    flags: np.ndarray
    motion: np.ndarray
    switch_times: np.ndarray

    @property
    def q(self) -> np.ndarray:
        """Generalized coordinates, shape (K, 9)."""
        return self.y[:, :9]

    def to_csv(self, path: str) -> None:
        """Write the trajectory as CSV with a header naming columns and SI units."""
        names = list(Q_NAMES) + [f"v_{n}" for n in Q_NAMES] + ["z_1", "z_2"]
        extra = ["theta_1_d", "theta_2_d", "max_CH_m", "max_CN_m_s", "flags"]
        header = ",".join(["t_s", "motion"] + names + extra)
        data = np.column_stack(
            [self.t, self.motion, self.y, self.setpoint, self.max_ch, self.max_cn, self.flags]
        )
        np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.12g")


def run_setpoint_sequence(
    setpoints_rad: Sequence[Sequence[float]] | np.ndarray,
    params: HandParams | None = None,
    duration: float = 1.0,
    record_interval: float = 1e-3,
    state0: np.ndarray | None = None,
    strict: bool = True,
) -> Trajectory:
    """Hold each set-point pair for ``duration`` seconds and record the run.

    Parameters
    ----------
    setpoints_rad : array_like, shape (M, 2)
        Finger-angle set-points (rad), one row per motion.
    params : HandParams, optional
        Defaults to Table 5.1.
    duration : float
        Time each motion is held (s); rounded to whole recording intervals.
    record_interval : float
        Recording interval (s); rounded to whole RK4 substeps.
    state0 : ndarray, shape (20,), optional
        Initial state (default: the paper's parallel point-contact state).
    strict : bool
        Raise :class:`~softhand_env.physics.PhysicsError` on divergence (else stop recording).

    Returns
    -------
    Trajectory
    """
    sp = np.asarray(setpoints_rad, dtype=float)
    if sp.ndim != 2 or sp.shape[1] != 2 or len(sp) == 0:
        raise ValueError(f"setpoints_rad must have shape (M, 2) (got {sp.shape})")
    if not np.all(np.isfinite(sp)):
        raise ValueError("setpoints_rad must be finite")
    if not (duration > 0 and record_interval > 0):
        raise ValueError("duration and record_interval must be > 0")
    physics = HandPhysics(params)
    physics.reset(state0)
    n_sub = max(1, round(record_interval / physics.dt))
    n_rec = max(1, round(duration / (n_sub * physics.dt)))
    K = 1 + len(sp) * n_rec
    y = np.empty((K, NY))
    setpoint = np.empty((K, 2))
    max_ch = np.empty(K)
    max_cn = np.empty(K)
    flags = np.zeros(K, dtype=np.int64)
    motion = np.zeros(K, dtype=np.int64)
    t = np.empty(K)
    diag = physics.diagnostics(sp[0])
    y[0], setpoint[0], t[0] = physics.get_state(), sp[0], 0.0
    max_ch[0], max_cn[0] = np.max(np.abs(diag["C_H"])), np.max(np.abs(diag["C_N"]))
    k = 1
    stopped = False
    for m, u in enumerate(sp):
        for _ in range(n_rec):
            status = physics.step(u, n_sub, strict=strict)
            y[k], setpoint[k], t[k], motion[k] = physics.get_state(), u, physics.time, m
            max_ch[k], max_cn[k], flags[k] = status.max_ch, status.max_cn, status.flags
            k += 1
            if status.fatal:
                stopped = True
                break
        if stopped:
            break
    switch = np.arange(len(sp)) * n_rec * n_sub * physics.dt
    return Trajectory(
        t[:k], y[:k], setpoint[:k], max_ch[:k], max_cn[:k], flags[:k], motion[:k], switch
    )


def run_paper_motions(
    params: HandParams | None = None, duration: float = 1.0, record_interval: float = 1e-3
) -> Trajectory:
    """Run motions 1-8 of §5.5.1 from the parallel point-contact state (see module doc)."""
    return run_setpoint_sequence(
        np.radians(PAPER_MOTIONS_DEG), params, duration=duration, record_interval=record_interval
    )
