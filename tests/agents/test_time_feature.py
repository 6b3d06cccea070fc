"""The episode-time feature: one env and the native vector env see the same observations."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from agents.sb3.native_vec_env import make_sb3_vec_env
from agents.wrappers.time_feature import TimeFeature, VecTimeFeature

ENV_ID = "SoftHandReorient-v0"
STEPS = 6
KWARGS = {"max_episode_steps": STEPS}


def test_single_and_native_agree_across_episode_ends(step_twins):
    n = 2
    venv = make_sb3_vec_env(ENV_ID, n, 7, KWARGS, "native",
                            env_wrapper=[{"agents.time_feature.TimeFeature":
                                          {"max_steps": STEPS}}])
    assert isinstance(venv, VecTimeFeature)
    singles = [TimeFeature(gym.make(ENV_ID, **KWARGS), max_steps=STEPS) for _ in range(n)]
    obs_v = venv.reset()
    obs_s = [e.reset(seed=7 + i)[0] for i, e in enumerate(singles)]
    np.testing.assert_array_equal(obs_v, np.stack(obs_s))
    assert np.all(obs_v[:, -1] == 1.0)
    rng = np.random.default_rng(0)
    dones_seen = 0
    for _ in range(2 * STEPS + 1):
        actions = rng.uniform(-0.2, 0.2, (n, 2)).astype(np.float32)
        obs_v, obs_s, ended = step_twins(venv, singles, actions)
        dones_seen += len(ended)
        np.testing.assert_array_equal(obs_v, obs_s)
    assert dones_seen >= n  # every env went through an episode end
    assert venv.observation_space.shape == singles[0].observation_space.shape


def test_feature_counts_down_and_rejects_bad_lengths():
    env = TimeFeature(gym.make(ENV_ID, max_episode_steps=4), max_steps=4)
    obs, _ = env.reset(seed=0)
    feats = [obs[-1]] + [env.step(np.zeros(2, np.float32))[0][-1] for _ in range(4)]
    np.testing.assert_allclose(feats, [1.0, 0.75, 0.5, 0.25, 0.0])
    assert env.observation_space.high[-1] == 1.0 and env.observation_space.low[-1] == 0.0
    for bad in (0, -1, 1.5, True, 10**7):
        with pytest.raises(ValueError, match="max_steps must be an int"):
            TimeFeature(gym.make(ENV_ID), max_steps=bad)


def test_dict_observations_get_the_feature_in_the_blind_part():
    env = TimeFeature(gym.make(ENV_ID, privileged_obs=True), max_steps=10)
    obs, _ = env.reset(seed=0)
    assert obs["observation"][-1] == 1.0
    plain = gym.make(ENV_ID, privileged_obs=True)
    ref, _ = plain.reset(seed=0)
    np.testing.assert_array_equal(obs["observation"][:-1], ref["observation"])
    np.testing.assert_array_equal(obs["privileged"], ref["privileged"])
