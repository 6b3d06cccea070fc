"""Observation features appended by wrappers (remaining time, action history).

A feature wrapper appends entries to a 1-D Box observation, or to the ``observation`` entry of
a Dict observation (the blind part the actor reads, :mod:`agents.sb3.policies`); the other Dict
entries are left as they are. :func:`space_with_entries` and :func:`append_entries` do this for
the space and for observations (one or a batch).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

#: Dict-observation key that receives the features.
KEY = "observation"


def space_with_entries(space: gym.Space, low: Any, high: Any, what: str) -> gym.Space:
    """``space`` with entries of bounds ``low``, ``high`` ((k,) each) appended, float32.

    ``what`` names the feature in the ValueError raised for any other space (e.g. "the time
    feature": "the time feature needs a 1-D Box or a Dict observation ...")."""
    def box(b: spaces.Box) -> spaces.Box:
        return spaces.Box(np.append(b.low.astype(np.float32), np.asarray(low, np.float32)),
                          np.append(b.high.astype(np.float32), np.asarray(high, np.float32)),
                          dtype=np.float32)

    if isinstance(space, spaces.Dict):
        if KEY not in space.spaces:
            raise ValueError(f"Dict observation has no {KEY!r} entry")
        return spaces.Dict({k: (box(v) if k == KEY else v)  # type: ignore[arg-type]
                            for k, v in space.spaces.items()})
    if isinstance(space, spaces.Box) and len(space.shape) == 1:
        return box(space)
    raise ValueError(f"{what} needs a 1-D Box or a Dict observation (got {space})")


def append_entries(obs: Any, values: np.ndarray) -> Any:
    """``obs`` (one (D,) or a batch (N, D), or a Dict of them) with ``values`` ((k,) or
    (N, k)) appended, float32."""
    if isinstance(obs, dict):
        out = dict(obs)
        out[KEY] = np.concatenate([obs[KEY], values], axis=-1).astype(np.float32)
        return out
    return np.concatenate([obs, values], axis=-1).astype(np.float32)
