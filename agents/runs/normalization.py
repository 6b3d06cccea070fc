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
    """Write the statistics of an SB3 ``VecNormalize`` to ``path`` (.npz).

    Box observations: ``obs_mean``, ``obs_var`` (obs_dim,), ``obs_count``. Dict observations:
    the same three arrays per normalised key, named ``obs_mean.<key>`` etc., and
    ``norm_obs_keys`` (the normalised keys, as a fixed-width unicode array, not pickled)."""
    rms = vecnormalize.obs_rms
    arrays: dict[str, Any] = {}
    if isinstance(rms, dict):
        keys = sorted(rms)
        for key in keys:
            arrays[f"obs_mean.{key}"] = np.asarray(rms[key].mean, dtype=np.float64)
            arrays[f"obs_var.{key}"] = np.asarray(rms[key].var, dtype=np.float64)
            arrays[f"obs_count.{key}"] = np.float64(rms[key].count)
        arrays["norm_obs_keys"] = np.array(keys, dtype=np.str_)
    else:
        arrays["obs_mean"] = np.asarray(rms.mean, dtype=np.float64)
        arrays["obs_var"] = np.asarray(rms.var, dtype=np.float64)
        arrays["obs_count"] = np.float64(rms.count)
    path = Path(path)
    with path.open("wb") as fh:  # np.savez would append .npz to other suffixes
        np.savez(
            fh,
            **arrays,
            clip_obs=np.float64(vecnormalize.clip_obs),
            epsilon=np.float64(vecnormalize.epsilon),
            norm_obs=np.bool_(vecnormalize.norm_obs),
            norm_reward=np.bool_(vecnormalize.norm_reward),
            gamma=np.float64(vecnormalize.gamma),
            ret_var=np.float64(np.asarray(vecnormalize.ret_rms.var).reshape(-1)[0]),
        )
    return path


#: Bounds on a statistics file, checked on its zip directory and array headers before any
#: array is read: members, elements per array, bytes per member.
MAX_NPZ_MEMBERS = 256
MAX_ELEMENTS = 1_000_000
MAX_NPZ_MEMBER_BYTES = 16 << 20
#: Allowed ``epsilon`` and ``clip_obs`` (VecNormalize's defaults are 1e-8 and 10).
EPSILON_RANGE = (1e-12, 1.0)
CLIP_RANGE = (1e-3, 1e6)


def check_npz_headers(path: str | Path) -> None:
    """ValueError unless every member of the ``.npz`` declares at most
    :data:`MAX_NPZ_MEMBER_BYTES` bytes and holds a plain (non-object) array of at most
    :data:`MAX_ELEMENTS` elements, read from its ``.npy`` header alone (nothing allocated)."""
    import zipfile

    from numpy.lib import format as npy

    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            if len(infos) > MAX_NPZ_MEMBERS:
                raise ValueError(f"{path}: more than {MAX_NPZ_MEMBERS} arrays")
            for info in infos:
                name = info.filename[:80]
                if info.file_size > MAX_NPZ_MEMBER_BYTES:
                    raise ValueError(f"{path}: array {name!r} declares {info.file_size} bytes")
                with archive.open(info) as fh:
                    version = npy.read_magic(fh)
                    read = (npy.read_array_header_1_0 if version == (1, 0)
                            else npy.read_array_header_2_0)
                    shape, _, dtype = read(fh, max_header_size=10_000)
                count = int(np.prod(shape, dtype=np.float64)) if shape else 1
                if dtype.hasobject or count > MAX_ELEMENTS or (
                        count * dtype.itemsize > info.file_size):
                    raise ValueError(f"{path}: array {name!r} has shape {shape[:4]} of "
                                     f"{dtype} (plain arrays of at most {MAX_ELEMENTS} "
                                     "elements that the file holds)")
    except (OSError, zipfile.BadZipFile, EOFError) as exc:
        raise ValueError(f"{path}: not a statistics file ({type(exc).__name__})") from None


def _moments(arrays: dict[str, np.ndarray], suffix: str, path: str | Path,
             size: int | None) -> tuple[np.ndarray, np.ndarray]:
    """(mean, var) of one observation (or one Dict key, ``suffix = ".<key>"``), checked."""
    mean = arrays["obs_mean" + suffix].astype(np.float64).reshape(-1)
    var = arrays["obs_var" + suffix].astype(np.float64).reshape(-1)
    if mean.shape != var.shape or np.any(var < 0):
        raise ValueError(f"{path}: obs_mean{suffix}/obs_var{suffix} must have one shape, var >= 0")
    if size is not None and mean.size != size:
        raise ValueError(f"{path}: statistics of {mean.size} observations{suffix}, the model "
                         f"has {size}")
    return mean, var


class ObsNormalizer:
    """Frozen observation normalisation read from a statistics file (:func:`save_stats`).

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file. Raises ``ValueError`` if it is not a statistics file (missing or
        non-numeric arrays, non-finite values, negative variances, a pickled array).
    obs_dim : int or dict, optional
        Observation size the statistics must have (Box), or key -> size (Dict observations:
        every normalised key must be one of them).
    """

    def __init__(self, path: str | Path, obs_dim: int | dict[str, int] | None = None):
        check_npz_headers(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                names = list(data.keys())
                keys = ([str(k) for k in data["norm_obs_keys"]] if "norm_obs_keys" in names
                        else None)
                per_key = [f"{m}.{k}" for k in keys or () for m in ("obs_mean", "obs_var",
                                                                   "obs_count")]
                wanted = [k for k in STATS_KEYS if keys is None or not k.startswith("obs_")]
                wanted = [k for k in wanted if k in names or k != "obs_count"]
                arrays = {k: np.asarray(data[k]) for k in wanted + per_key}
        except KeyError as exc:
            raise ValueError(f"{path}: missing array {exc}") from None
        except (OSError, ValueError) as exc:  # not an npz, or an object (pickled) array
            raise ValueError(f"{path}: not a statistics file ({exc})") from None
        for key, arr in arrays.items():
            if arr.dtype.kind not in "fbiu" or not np.all(np.isfinite(arr)):
                raise ValueError(f"{path}: {key} must hold finite numbers")
        self.keys = keys
        self.moments: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        #: Observations the moments were averaged over (None: a Box; key -> count: a Dict).
        self.count = (float(arrays["obs_count"]) if keys is None and "obs_count" in arrays
                      else None)
        self.counts = {k: float(arrays[f"obs_count.{k}"]) for k in keys or ()}
        if keys is None:
            if isinstance(obs_dim, dict):
                raise ValueError(f"{path}: statistics of a Box observation, the model has a "
                                 "Dict observation")
            self.mean, self.var = _moments(arrays, "", path, obs_dim)
        else:
            if obs_dim is not None and not isinstance(obs_dim, dict):
                raise ValueError(f"{path}: statistics of a Dict observation, the model has a "
                                 "Box observation")
            for k in keys:
                if obs_dim is not None and k not in obs_dim:
                    raise ValueError(f"{path}: statistics of key {k!r}, which the model's "
                                     f"observation lacks ({sorted(obs_dim)})")
                self.moments[k] = _moments(arrays, f".{k}", path,
                                           None if obs_dim is None else obs_dim[k])
        self.clip_obs = float(arrays["clip_obs"])
        self.epsilon = float(arrays["epsilon"])
        self.norm_obs = bool(arrays["norm_obs"])
        if not (EPSILON_RANGE[0] <= self.epsilon <= EPSILON_RANGE[1]
                and CLIP_RANGE[0] <= self.clip_obs <= CLIP_RANGE[1]):
            raise ValueError(f"{path}: epsilon must be in [{EPSILON_RANGE[0]:g}, "
                             f"{EPSILON_RANGE[1]:g}] and clip_obs in [{CLIP_RANGE[0]:g}, "
                             f"{CLIP_RANGE[1]:g}] (got {self.epsilon:g}, {self.clip_obs:g})")

    def load_into(self, vecnormalize: Any) -> None:
        """Copy these moments (and counts, where stored) into the running statistics of an SB3
        ``VecNormalize`` (the inverse of :func:`save_stats` for the moments; its observation
        keys must be these)."""
        rms = vecnormalize.obs_rms
        if self.keys is None:
            rms.mean, rms.var = self.mean.copy(), self.var.copy()
            rms.count = self.count or rms.count
            return
        for key, (mean, var) in self.moments.items():
            rms[key].mean, rms[key].var = mean.copy(), var.copy()
            rms[key].count = self.counts.get(key) or rms[key].count

    def _one(self, obs: np.ndarray, mean: np.ndarray, var: np.ndarray) -> np.ndarray:
        with np.errstate(over="ignore"):  # a huge quotient is clipped below
            z = (obs - mean) / np.sqrt(var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def __call__(self, obs: Any) -> Any:
        """Normalised observation(s): an array (..., obs_dim) -> float32 of its shape; a dict
        -> a dict with the normalised keys replaced (the others as given)."""
        if not self.norm_obs:
            return obs if isinstance(obs, dict) else np.asarray(obs)
        if self.keys is None:
            return self._one(obs, self.mean, self.var)
        if not isinstance(obs, dict):
            raise TypeError("these statistics normalise Dict observations; got an array")
        return {k: (self._one(v, *self.moments[k]) if k in self.moments else v)
                for k, v in obs.items()}
