"""The action-history feature: one env and the native vector env see the same observations."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from agents.sb3.native_vec_env import make_sb3_vec_env
from agents.wrappers.action_history import ActionHistory, VecActionHistory

ENV_ID = "SoftHandReorient-v0"
STEPS = 5
KWARGS = {"max_episode_steps": STEPS}
WRAPPER = [{"agents.action_history.ActionHistory": {"n": 2}}]


def test_single_and_native_agree_across_episode_ends(step_twins):
    n = 2
    venv = make_sb3_vec_env(ENV_ID, n, 3, KWARGS, "native", env_wrapper=WRAPPER)
    assert isinstance(venv, VecActionHistory)
    singles = [ActionHistory(gym.make(ENV_ID, **KWARGS), n=2) for _ in range(n)]
    obs_v = venv.reset()
    np.testing.assert_array_equal(obs_v, np.stack([e.reset(seed=3 + i)[0]
                                                   for i, e in enumerate(singles)]))
    np.testing.assert_array_equal(obs_v[:, -4:], 0.0)  # no action yet
    rng = np.random.default_rng(0)
    previous = np.zeros((n, 2), np.float32)
    dones_seen = 0
    for _ in range(2 * STEPS + 1):
        actions = rng.uniform(-1.5, 1.5, (n, 2)).astype(np.float32)  # clipped in the feature
        obs_v, obs_s, ended = step_twins(venv, singles, actions)
        for i, last in ended:  # an episode's last observation holds its last two actions
            np.testing.assert_array_equal(last[-4:], np.clip(
                np.concatenate([actions[i], previous[i]]), -1, 1))
            np.testing.assert_array_equal(obs_s[i, -4:], 0.0)  # a new episode starts empty
        dones_seen += len(ended)
        np.testing.assert_array_equal(obs_v, obs_s)
        previous = actions
    assert dones_seen >= n


def test_dict_observations_and_bad_arguments():
    env = ActionHistory(gym.make(ENV_ID, privileged_obs=True), n=3)
    obs, _ = env.reset(seed=0)
    assert env.observation_space["observation"].shape == (obs["observation"].shape[0],)
    obs, *_ = env.step(np.array([0.5, -0.25], np.float32))
    np.testing.assert_array_equal(obs["observation"][-6:], [0.5, -0.25, 0, 0, 0, 0])
    assert "privileged" in obs and obs["privileged"].shape == (17,)
    for bad in (0, -1, 1.5, True, 101):
        with pytest.raises(ValueError, match="n must be an int"):
            ActionHistory(gym.make(ENV_ID), n=bad)
