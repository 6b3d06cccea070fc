"""Observation-normalisation statistics as plain arrays (``.npz``), never pickle.

SB3's ``VecNormalize.save`` pickles the whole wrapper; loading such a file runs whatever code
it names. Runs therefore also store the statistics with :func:`save_stats` as an ``.npz`` of
plain arrays (``obs_mean``, ``obs_var`` (obs_dim,), ``clip_obs``, ``epsilon``, ``norm_obs``,
...), read back by :class:`ObsNormalizer` with ``numpy.load(allow_pickle=False)``. The
normalisation is VecNormalize's (frozen statistics)::

    clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)  as float32
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

#: Arrays of a statistics file (all required).
STATS_KEYS = ("obs_mean", "obs_var", "obs_count", "clip_obs", "epsilon", "norm_obs",
              "norm_reward", "gamma", "ret_var")


def save_stats(vecnormalize: Any, path: str | Path) -> Path:
    """Write the statistics of an SB3 ``VecNormalize`` (Box observations) to ``path`` (.npz)."""
    rms = vecnormalize.obs_rms
    if isinstance(rms, dict):
        raise TypeError("dict observations: statistics per key are not supported")
    path = Path(path)
    with path.open("wb") as fh:  # np.savez would append .npz to other suffixes
        np.savez(
            fh,
            obs_mean=np.asarray(rms.mean, dtype=np.float64),
            obs_var=np.asarray(rms.var, dtype=np.float64),
            obs_count=np.float64(rms.count),
            clip_obs=np.float64(vecnormalize.clip_obs),
            epsilon=np.float64(vecnormalize.epsilon),
            norm_obs=np.bool_(vecnormalize.norm_obs),
            norm_reward=np.bool_(vecnormalize.norm_reward),
            gamma=np.float64(vecnormalize.gamma),
            ret_var=np.float64(np.asarray(vecnormalize.ret_rms.var).reshape(-1)[0]),
        )
    return path


class ObsNormalizer:
    """Frozen observation normalisation read from a statistics file (:func:`save_stats`).

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file. Raises ``ValueError`` if it is not a statistics file (missing or
        non-numeric arrays, non-finite values, negative variances, a pickled array).
    obs_dim : int, optional
        Observation size the statistics must have.
    """

    def __init__(self, path: str | Path, obs_dim: int | None = None):
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: np.asarray(data[k]) for k in STATS_KEYS}
        except KeyError as exc:
            raise ValueError(f"{path}: missing array {exc}") from None
        except (OSError, ValueError) as exc:  # not an npz, or an object (pickled) array
            raise ValueError(f"{path}: not a statistics file ({exc})") from None
        for key, arr in arrays.items():
            if arr.dtype.kind not in "fbiu" or not np.all(np.isfinite(arr)):
                raise ValueError(f"{path}: {key} must hold finite numbers")
        self.mean = arrays["obs_mean"].astype(np.float64).reshape(-1)
        self.var = arrays["obs_var"].astype(np.float64).reshape(-1)
        if self.mean.shape != self.var.shape or np.any(self.var < 0):
            raise ValueError(f"{path}: obs_mean/obs_var must have one shape, var >= 0")
        if obs_dim is not None and self.mean.size != obs_dim:
            raise ValueError(f"{path}: statistics of {self.mean.size} observations, the model "
                             f"has {obs_dim}")
        self.clip_obs = float(arrays["clip_obs"])
        self.epsilon = float(arrays["epsilon"])
        self.norm_obs = bool(arrays["norm_obs"])
        if self.clip_obs <= 0 or self.epsilon <= 0:
            raise ValueError(f"{path}: clip_obs and epsilon must be > 0")

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Normalised observation(s), shape of ``obs`` (..., obs_dim), float32."""
        if not self.norm_obs:
            return np.asarray(obs)
        z = (obs - self.mean) / np.sqrt(self.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)
