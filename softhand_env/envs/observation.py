"""Observations: what the hand senses at its joints (and, optionally, in its fingertips).

The observation is a pure function of the hand's joint read-outs (angles, velocities, set-points,
PID torques) and, optionally, its fingertip deformations (:func:`observe_rows`); it never reads
the object's pose or velocity. Information
about the object that reaches the joints through the contact forces over time (joint angles
lagging their set-points, PID torques) is *sensing* and allowed: that is what blind
manipulation means here.

Layout of one frame (float32, in this order, each divided by its scale)::

    index  name        quantity                               unit    scale
    0, 1   theta_1/2   joint angles                           rad     ANGLE_SCALE (30 deg)
    2, 3   omega_1/2   joint velocities                       rad/s   VELOCITY_SCALE (5)
    4, 5   setpoint_1/2 current PID set-points                rad     ANGLE_SCALE
    6, 7   torque_1/2  PID torques (Eq 5.42)                  N m     TORQUE_SCALE (10)
    8, 9   d_n1/2      normal fingertip deformation [tactile] m       DN_SCALE (10 mm)
    10, 11 d_t1/2      tangential deformation [tactile]       m       DT_SCALE (1 mm)

The observation is ``history_len`` frames, newest first, then (``onset_obs=True``) the two
joint angles read at the start of the grasp phase, where the fingertips touch the object
undeformed (``onset_theta_1/2``, / ANGLE_SCALE, read once per episode through the sensor
model), then the goal of goal tasks (x target / POSITION_SCALE (30 mm), theta target /
ANGLE_SCALE). Every entry is clipped to [-OBS_BOUND, OBS_BOUND] = [-100, 100], the bounds of
the observation space.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces
from numba import njit

from softhand_env.envs.options import KEYWORDS, check_keyword
from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)

#: Angles (rad) are divided by this (30 deg).
ANGLE_SCALE = math.radians(30.0)
#: Joint velocities (rad/s) are divided by this.
VELOCITY_SCALE = 5.0
#: PID torques (N m) are divided by this.
TORQUE_SCALE = 10.0
#: Normal deformations d_n (m) are divided by this (the model's validity limit a/2 of Table 5.1).
DN_SCALE = 0.01
#: Tangential deformations d_t (m) are divided by this.
DT_SCALE = 0.001
#: Object x targets (m) are divided by this.
POSITION_SCALE = 0.03
#: Every observation entry is clipped to [-OBS_BOUND, OBS_BOUND] (the observation space bounds;
#: reached only by PID torque spikes above 1000 N m or a diverging state).
OBS_BOUND = 100.0

#: Largest ``history_len`` (frames): bounds the observation size before anything is allocated.
MAX_HISTORY = int(KEYWORDS["history_len"].high)

PROPRIO_NAMES = (
    "theta_1",
    "theta_2",
    "omega_1",
    "omega_2",
    "setpoint_1",
    "setpoint_2",
    "torque_1",
    "torque_2",
)
TACTILE_NAMES = ("d_n1", "d_n2", "d_t1", "d_t2")
#: Names of the grasp-onset entries (``onset_obs``), after the frames.
ONSET_NAMES = ("onset_theta_1", "onset_theta_2")
OBS_MODES = KEYWORDS["obs_mode"].choices


@njit(cache=True)
def _clip(v):
    return min(max(v, -OBS_BOUND), OBS_BOUND)


@njit(cache=True)
def observe_rows(theta, omega, setpoint, torque, deformation, tactile, out):
    """Write one scaled frame per hand into ``out[s, :8]`` (``out[s, :12]`` with ``tactile``).

    Parameters
    ----------
    theta, omega : ndarray, shape (N, 2)
        Joint angles (rad) and velocities (rad/s).
    setpoint : ndarray, shape (N, 2)
        Set-points (rad).
    torque : ndarray, shape (N, 2)
        PID torques (N m).
    deformation : ndarray, shape (N, 4)
        d_n1, d_n2, d_t1, d_t2 (m); read only with ``tactile``.
    tactile : bool
        Append the deformations.
    out : ndarray, shape (N, >= frame size)
        Output (any float dtype).
    """
    for s in range(out.shape[0]):  # element by element: a row view per hand costs more
        out[s, 0] = _clip(theta[s, 0] / ANGLE_SCALE)
        out[s, 1] = _clip(theta[s, 1] / ANGLE_SCALE)
        out[s, 2] = _clip(omega[s, 0] / VELOCITY_SCALE)
        out[s, 3] = _clip(omega[s, 1] / VELOCITY_SCALE)
        out[s, 4] = _clip(setpoint[s, 0] / ANGLE_SCALE)
        out[s, 5] = _clip(setpoint[s, 1] / ANGLE_SCALE)
        out[s, 6] = _clip(torque[s, 0] / TORQUE_SCALE)
        out[s, 7] = _clip(torque[s, 1] / TORQUE_SCALE)
        if tactile:
            out[s, 8] = _clip(deformation[s, 0] / DN_SCALE)
            out[s, 9] = _clip(deformation[s, 1] / DN_SCALE)
            out[s, 10] = _clip(deformation[s, 2] / DT_SCALE)
            out[s, 11] = _clip(deformation[s, 3] / DT_SCALE)


class ObservationLayout:
    """Sizes and names of the observation vector.

    Parameters
    ----------
    obs_mode : str
        ``"proprio"`` or ``"proprio_tactile"``.
    history_len : int
        Number of frames (>= 1), newest first.
    goal_names : tuple of str
        Names of the goal entries appended at the end.
    onset : bool
        The two grasp-onset angles follow the frames (``onset_obs``; columns
        ``history_size .. history_size + onset_size``).
    """

    def __init__(self, obs_mode: str, history_len: int, goal_names: tuple[str, ...],
                 onset: bool = False):
        check_keyword("obs_mode", obs_mode)
        check_keyword("history_len", history_len)
        #: The ``obs_mode`` keyword the layout was built from.
        self.obs_mode = obs_mode
        self.tactile = obs_mode == "proprio_tactile"
        self.history_len = int(history_len)
        frame = PROPRIO_NAMES + (TACTILE_NAMES if self.tactile else ())
        self.frame_size = len(frame)
        self.history_size = self.frame_size * self.history_len
        self.onset = bool(onset)
        self.onset_size = len(ONSET_NAMES) if self.onset else 0
        #: Entries before the goal: the frames, then the onset entries.
        self.blind_size = self.history_size + self.onset_size
        self.goal_size = len(goal_names)
        self.size = self.blind_size + self.goal_size
        names = [n if k == 0 else f"{n}[t-{k}]" for k in range(self.history_len) for n in frame]
        self.names = (tuple(names) + (ONSET_NAMES if self.onset else ())
                      + tuple(f"goal_{g}" for g in goal_names))

    def space(self) -> spaces.Box:
        """float32 Box [-OBS_BOUND, OBS_BOUND]^size."""
        return spaces.Box(-OBS_BOUND, OBS_BOUND, shape=(self.size,), dtype=np.float32)


def add_frame_noise(frame: np.ndarray, std: float, rng: np.random.Generator) -> None:
    """Add N(0, std^2) noise (scaled units) to one frame in place, drawn from ``rng``; clip."""
    # the draw from the generator, the sum and the clip in one compiled call (three ufunc
    # calls cost microseconds a frame)
    _add_clipped(frame, rng.normal(0.0, std, size=frame.shape[-1]))


def standard_normal_rows(rngs: Sequence[np.random.Generator], size: int) -> np.ndarray:
    """Standard normal draws (K, size), row k from ``rngs[k]`` (written in place: the numbers
    of ``rngs[k].standard_normal(size)``)."""
    z = np.empty((len(rngs), size))
    for row, rng in zip(z, rngs, strict=True):
        rng.standard_normal(out=row)
    return z


def add_frame_noise_rows(obs: np.ndarray, rows: np.ndarray, size: int, std: float,
                         rngs: Sequence[np.random.Generator]) -> None:
    """:func:`add_frame_noise` of the frames ``obs[i, :size]`` of the rows ``rows`` (int (K,))
    of ``obs`` (float32 (N, obs_size)), row ``rows[k]`` drawing from ``rngs[k]``: the same
    draws and numbers, the sums and clips of all rows in one compiled call."""
    noise = standard_normal_rows(rngs, size)
    noise *= std
    noise += 0.0  # as Generator.normal(0.0, std) computes loc + scale * z (the sign of 0)
    _add_clipped_rows(obs, np.asarray(rows, dtype=np.int64), noise)


@njit(cache=True)
def _add_clipped_rows(obs, rows, noise):
    """obs[rows[k], :size] += noise[k] (noise (K, size)) as :func:`_add_clipped`, per row."""
    for k in range(rows.shape[0]):
        _add_clipped(obs[rows[k], : noise.shape[1]], noise[k])


@njit(cache=True)
def _add_clipped(frame, noise):
    """frame (float32, (size,)) += noise (float64, (size,)), rounded to float32 and clipped
    to [-OBS_BOUND, OBS_BOUND] in place (NaN stays NaN)."""
    lo, hi = np.float32(-OBS_BOUND), np.float32(OBS_BOUND)
    for j in range(frame.shape[0]):
        x = np.float32(frame[j] + noise[j])
        if x < lo:
            x = lo
        elif x > hi:
            x = hi
        frame[j] = x
