"""Fixtures of the agents tests: one step of an SB3 VecEnv next to its single-env twins, and a
local Ray for the sharding tests."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest


def _step_twins(venv: Any, singles: list[gym.Env], actions: np.ndarray
                ) -> tuple[Any, np.ndarray, list[tuple[int, Any]]]:
    """Step an SB3 VecEnv and its single-env twins with the same actions (N, A). Checks that
    the twins' episode ends are the VecEnv's dones and their last observations its
    ``terminal_observation``; resets the ended twins. Returns the VecEnv's observations, the
    twins' (stacked, after any reset) and the (index, last observation) of the ended ones."""
    obs_v, _, dones, infos = venv.step(actions)
    obs_s, ended = [], []
    for i, env in enumerate(singles):
        o, _, term, trunc, _ = env.step(actions[i])
        if term or trunc:
            assert dones[i]
            np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
            ended.append((i, o))
            o, _ = env.reset()
        obs_s.append(o)
    return obs_v, np.stack(obs_s), ended


@pytest.fixture
def step_twins() -> Callable[..., Any]:
    """:func:`_step_twins`: one step of an SB3 VecEnv and its single-env twins."""
    return _step_twins


@pytest.fixture(scope="module")
def local_ray():
    """A Ray of this machine with 2 CPUs for one test module (started with
    ``address="local"``, so never a cluster a ``ray start`` left behind), shut down after it;
    the module is skipped where Ray is not installed."""
    ray = pytest.importorskip("ray")
    started = not ray.is_initialized()
    if started:
        ray.init(address="local", num_cpus=2, include_dashboard=False)
    yield ray
    if started:
        ray.shutdown()
