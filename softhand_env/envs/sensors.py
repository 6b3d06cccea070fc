"""Sensor models: what the hand's joint encoders, current sensors and fingertips report.

The keyword ``sensor_model`` chooses how the observation reads the hand:

* ``"ideal"``: the exact read-outs of the simulation (joint angles and velocities, PID
  torques, fingertip deformations), as the ``-v0`` ids have always observed them. Nothing is
  drawn from the random generator.
* ``"realistic"`` (the ``-v1`` ids): the values of ``configs/sensors/realistic.yaml`` (units in
  the key names; rationale in ``docs/sensors.md``), applied by :class:`SensorState`:

  - **joint angle**: a quantised encoder, theta_meas = q round((theta + n) / q), q the
    resolution ``encoder_resolution_deg``, n ~ N(0, s^2) per reading, s = ``encoder_noise_deg``;
  - **joint velocity**: the finite difference of two successive encoder readings over the
    control period, (theta_meas(t) - theta_meas(t - dt)) / dt (0 at reset), so it is
    quantised in steps of q / dt and carries the encoder noise (sqrt(2) n / dt);
  - **joint torque** (motor current times the torque constant): tau_meas = g tau + b + m,
    tau the PID torque, b a per-episode offset ~ N(0, s_b^2) per joint
    (s_b = ``torque_bias_nm``), m ~ N(0, s_m^2) per reading (s_m = ``torque_noise_nm``),
    g the torque-constant gain, 1 unless
    ``rand_sensors=True``, which draws it per episode and joint from 1 + U(-t, t), t =
    ``torque_gain_tolerance``;
  - **fingertip deformation** (``obs_mode="proprio_tactile"``): d + N(0, s_d^2) on each of
    d_n1, d_n2, d_t1, d_t2, s_d = ``tactile_noise_mm``.

  The set-point entries are the commands the controller holds, known exactly.

Every draw comes from the environment's ``np_random``, so a seeded episode is reproducible and
environment i of the native vector env draws what a single environment with its seed draws.
Per episode, after everything :func:`~softhand_env.envs.start.start_episode` draws: the two
torque offsets, then (``rand_sensors=True``) the two gains, then (``onset_obs=True``) the two
encoder noises of the grasp-onset reading. Per reading (each reset and each
step): two encoder noises, two torque noises, then four tactile noises (tactile mode). The
observation's ``obs_noise`` (scaled units) is added after the sensor model, drawn after it.
The sensed values go through the observation's scaling (:mod:`.observation`), so the
observation stays O(1); ``info`` keeps the true values (``deformation``, ``setpoint``,
``object_pose``), and ``env.unwrapped.physics`` the true joint read-outs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from softhand_env.envs.observation import standard_normal_rows
from softhand_env.envs.options import KEYWORDS
from softhand_env.physics import jit_cache  # noqa: F401  (the package stamp on cached kernels)

SENSOR_CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs" / "sensors"

#: Sensor-model names (the ``sensor_model`` keyword's choices).
SENSOR_MODELS = KEYWORDS["sensor_model"].choices

#: YAML key -> allowed range (low, high); the low end is open for the encoder resolution.
RANGES: dict[str, tuple[float, float]] = {
    "encoder_resolution_deg": (0.0, 10.0),
    "encoder_noise_deg": (0.0, 10.0),
    "torque_noise_nm": (0.0, 100.0),
    "torque_bias_nm": (0.0, 100.0),
    "torque_gain_tolerance": (0.0, 0.5),
    "tactile_noise_mm": (0.0, 10.0),
}


@dataclass(frozen=True)
class SensorSpec:
    """One sensor model's values (units in the names; all 0 for ``"ideal"``).

    Attributes
    ----------
    name : str
        ``"ideal"`` or the YAML's name.
    encoder_resolution_deg : float
        Encoder count (deg).
    encoder_noise_deg : float
        rms noise of an encoder reading before quantisation (deg).
    torque_noise_nm : float
        rms noise of a torque reading (N m).
    torque_bias_nm : float
        Standard deviation of the per-episode torque offset (N m).
    torque_gain_tolerance : float
        Relative half-width of the per-episode torque gain (with ``rand_sensors=True``).
    tactile_noise_mm : float
        rms noise of a fingertip deformation reading (mm).
    """

    name: str = "ideal"
    encoder_resolution_deg: float = 0.0
    encoder_noise_deg: float = 0.0
    torque_noise_nm: float = 0.0
    torque_bias_nm: float = 0.0
    torque_gain_tolerance: float = 0.0
    tactile_noise_mm: float = 0.0

    @property
    def ideal(self) -> bool:
        """The exact read-outs (no sensor model applied)."""
        return self.name == "ideal"

    def scaled(self, scale: float) -> SensorSpec:
        """This model with its random errors multiplied by ``scale`` (>= 0, dimensionless):
        ``encoder_noise_deg``, ``torque_noise_nm``, ``torque_bias_nm`` and
        ``tactile_noise_mm``. The encoder resolution (quantisation) and the torque-gain
        tolerance (the ``rand_sensors`` randomisation) are kept. ``scale=0`` leaves quantised
        encoders (and encoder-differenced velocities) with exact torques and fingertips; the
        generator draws the same numbers at every scale. The name is kept (the
        ``sensor_noise_scale`` keyword records the scale)."""
        if not (math.isfinite(scale) and scale >= 0.0):
            raise ValueError(f"scale must be a finite number >= 0 (got {scale!r})")
        return replace(self, encoder_noise_deg=scale * self.encoder_noise_deg,
                       torque_noise_nm=scale * self.torque_noise_nm,
                       torque_bias_nm=scale * self.torque_bias_nm,
                       tactile_noise_mm=scale * self.tactile_noise_mm)

    def as_dict(self) -> dict[str, Any]:
        """The values as the YAML holds them, with the name."""
        return asdict(self)


def load_sensor_spec(name: str) -> SensorSpec:
    """The sensor model ``name`` (``"ideal"`` or ``configs/sensors/<name>.yaml``).

    The YAML (read with ``yaml.safe_load``) must hold exactly the keys of :data:`RANGES`,
    each a finite number in its range; ``ValueError`` names the file, the key and the range.
    """
    import yaml

    if name not in SENSOR_MODELS:
        raise ValueError(f"sensor_model must be one of {SENSOR_MODELS} (got {name!r})")
    if name == "ideal":
        return SensorSpec()
    path = SENSOR_CONFIG_DIR / f"{name}.yaml"
    with path.open() as fh:
        data = yaml.safe_load(fh) or {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping")
    missing, unknown = sorted(set(RANGES) - set(data)), sorted(set(data) - set(RANGES))
    if missing or unknown:
        raise ValueError(f"{path}: missing keys {missing}, unknown keys {unknown}")
    values = {}
    for key, (low, high) in RANGES.items():
        v = data[key]
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        low_ok = ok and (v > low if key == "encoder_resolution_deg" else v >= low)
        if not (low_ok and v <= high):
            bracket = "(" if key == "encoder_resolution_deg" else "["
            raise ValueError(f"{path}: {key} must be a number in {bracket}{low:g}, {high:g}] "
                             f"(got {v!r})")
        values[key] = float(v)
    return SensorSpec(name=name, **values)


class SensorState:
    """The sensors of N hands under a non-ideal :class:`SensorSpec` (see the module doc).

    Parameters
    ----------
    spec : SensorSpec
    num_envs : int
    dt : float
        Control period (s), the encoders' differencing interval.
    tactile : bool
        The observation reads the fingertip deformations.
    rand_gain : bool
        Draw each episode's torque gain (``rand_sensors``).

    Attributes
    ----------
    torque_bias : ndarray, shape (N, 2)
        Per-episode torque offsets (N m).
    torque_gain : ndarray, shape (N, 2)
        Per-episode torque gains (1 without ``rand_gain``).
    angle : ndarray, shape (N, 2)
        Last encoder readings (rad).
    """

    def __init__(self, spec: SensorSpec, num_envs: int, dt: float, tactile: bool,
                 rand_gain: bool):
        if spec.ideal:
            raise ValueError("SensorState models non-ideal sensors; 'ideal' reads the state")
        self.spec = spec
        self.dt = float(dt)
        self.tactile = bool(tactile)
        self.rand_gain = bool(rand_gain)
        self.resolution = math.radians(spec.encoder_resolution_deg)
        self.encoder_noise = math.radians(spec.encoder_noise_deg)
        self.tactile_noise = spec.tactile_noise_mm * 1e-3
        self.torque_bias = np.zeros((num_envs, 2))
        self.torque_gain = np.ones((num_envs, 2))
        self.angle = np.zeros((num_envs, 2))
        self._draws = 8 if self.tactile else 4

    def start(self, i: int, rng: np.random.Generator) -> None:
        """Draw the calibration of environment ``i``'s new episode from ``rng``."""
        self.torque_bias[i] = rng.normal(0.0, self.spec.torque_bias_nm, size=2)
        if self.rand_gain:
            t = self.spec.torque_gain_tolerance
            self.torque_gain[i] = 1.0 + t * rng.uniform(-1.0, 1.0, size=2)

    def onset(self, angle: np.ndarray, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """Encoder readings (K, 2) (rad) of the joint angles ``angle`` (K, 2) (rad) of K
        environments, row k with two N(0, s^2) noises drawn from ``rngs[k]`` and rounded to
        the resolution, as every encoder reading (the grasp-onset entries, ``onset_obs``)."""
        angle = np.asarray(angle, dtype=np.float64)
        z = standard_normal_rows(rngs, 2) if len(rngs) else np.zeros((0, 2))
        return _encoder_reading(angle, z, self.resolution, self.encoder_noise)

    def read(
        self,
        angle: np.ndarray,
        torque: np.ndarray,
        deformation: np.ndarray,
        rows: Sequence[int] | np.ndarray,
        rngs: Sequence[np.random.Generator],
        first: bool,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Sensed (angle, velocity, torque, deformation) of the environments ``rows``.

        Parameters
        ----------
        angle : ndarray, shape (N, 2)
            True joint angles (rad).
        torque : ndarray, shape (N, 2)
            True PID torques (N m).
        deformation : ndarray, shape (N, 4)
            True d_n1, d_n2, d_t1, d_t2 (m).
        rows : sequence of int
            Environments read now.
        rngs : sequence of generators
            The generator of each environment of ``rows`` (in that order).
        first : bool
            The first reading of an episode (velocity 0).

        Returns
        -------
        angle (N, 2) rad, velocity (N, 2) rad/s, torque (N, 2) N m, deformation (N, 4) m:
        fresh arrays; rows not in ``rows`` hold the true values (velocity 0).
        """
        q = self.resolution
        theta = np.array(angle, dtype=np.float64)
        omega = np.zeros_like(theta)
        tau = np.array(torque, dtype=np.float64)
        d = np.array(deformation, dtype=np.float64)
        rows = np.asarray(rows, dtype=np.int64)
        if len(rngs) != rows.size:
            raise ValueError(f"one generator per row: {rows.size} rows, {len(rngs)} generators")
        # each environment's draws from its own generator, then every row in one compiled call
        z = standard_normal_rows(rngs, self._draws)
        _sense_rows(theta, omega, tau, d, rows, z, q, self.encoder_noise,
                    self.spec.torque_noise_nm, self.tactile_noise, self.dt, first,
                    self.tactile, self.angle, self.torque_gain, self.torque_bias)
        return theta, omega, tau, d


@njit(cache=True)
def _encoder_reading(theta, z, q, encoder_noise):
    """Encoder reading(s) of the joint angle(s) theta (rad; a float or an array): theta plus
    encoder_noise (rad) times the standard normal draw(s) z, rounded to the resolution q
    (rad)."""
    return q * np.rint((theta + encoder_noise * z) / q)


@njit(cache=True)
def _sense_rows(theta, omega, tau, d, rows, z, q, encoder_noise, torque_noise, tactile_noise,
                dt, first, tactile, angle, gain, bias):
    """The readings of the rows ``rows`` (int (K,)) in place, from the standard normal draws
    z (K, 4 or 8) of each row (encoder 2, torque 2, tactile 4): encoder angles theta (N, 2)
    rounded to the resolution q (rad) after N(0, encoder_noise^2) noise, their difference
    quotient over dt (s) into omega (N, 2) unless ``first``, the readings kept in angle
    (N, 2); torques tau (N, 2) = gain * tau + bias + N(0, torque_noise^2) (N m); with
    ``tactile`` d (N, 4) += N(0, tactile_noise^2) (m)."""
    for k in range(rows.shape[0]):
        i = rows[k]
        for j in range(2):
            reading = _encoder_reading(theta[i, j], z[k, j], q, encoder_noise)
            if not first:
                omega[i, j] = (reading - angle[i, j]) / dt
            angle[i, j] = reading
            theta[i, j] = reading
            tau[i, j] = gain[i, j] * tau[i, j] + bias[i, j] + torque_noise * z[k, 2 + j]
        if tactile:
            for j in range(4):
                d[i, j] += tactile_noise * z[k, 4 + j]


__all__ = ["RANGES", "SENSOR_MODELS", "SensorSpec", "SensorState", "load_sensor_spec"]

