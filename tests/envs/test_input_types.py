"""Input types of the environments: pair keywords, torch actions, seeds (the same rule in the
single and the vector env), the vector env's num_envs and max_episode_steps."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401  (registers the ids)

ID = "SoftHandTranslate-v0"


def _vector(**kwargs):
    return gym.make_vec(ID, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("value", ["66", ("6", "6"), ["6", 6], b"66", (6.0,), (6, 6, 6),
                                   (True, 6), {6, 7}, np.ones((1, 2)) * 6])
def test_pair_keywords_take_two_numbers_only(value):
    with pytest.raises(ValueError, match="grasp_setpoint_deg must be a pair"):
        gym.make(ID, grasp_setpoint_deg=value)
    with pytest.raises(ValueError, match="grasp_setpoint_deg must be a pair"):
        _vector(num_envs=2, grasp_setpoint_deg=value)


@pytest.mark.parametrize("value", [(6, 6), [6.0, 6.5], np.array([6.0, 6.0]),
                                   (np.float32(6), np.int64(6))])
def test_pair_keywords_accept_tuples_lists_and_arrays(value):
    gym.make(ID, grasp_setpoint_deg=value).close()


def test_torch_actions_convert_or_are_a_type_error():
    torch = pytest.importorskip("torch")
    env = gym.make(ID)
    env.reset(seed=0)
    obs_np = env.step(np.zeros(2, dtype=np.float32))[0]
    env.reset(seed=0)
    obs_t = env.step(torch.zeros(2))[0]  # a CPU tensor converts
    np.testing.assert_array_equal(obs_np, obs_t)
    with pytest.raises(TypeError, match="detach"):
        env.step(torch.zeros(2, requires_grad=True))
    env.close()
    vec = _vector(num_envs=2)  # the native vector env: the same rule
    vec.reset(seed=0)
    obs_np = vec.step(np.zeros((2, 2), dtype=np.float32))[0]
    vec.reset(seed=0)
    np.testing.assert_array_equal(vec.step(torch.zeros(2, 2))[0], obs_np)
    with pytest.raises(TypeError, match="detach"):
        vec.step(torch.zeros(2, 2, requires_grad=True))
    vec.close()


@pytest.mark.parametrize("seed", [3, np.int64(3), np.uint32(3), 2**40])
def test_seeds_accepted_alike(seed):
    env = gym.make(ID)
    vec = _vector(num_envs=2)
    env.reset(seed=seed)
    vec.reset(seed=seed)
    vec.reset(seed=[seed, None])
    env.close()
    vec.close()


@pytest.mark.parametrize("seed,error", [(True, TypeError), (3.0, TypeError), ("3", TypeError),
                                        (-1, ValueError), (np.int64(-2), ValueError)])
def test_seeds_refused_alike(seed, error):
    env = gym.make(ID)
    vec = _vector(num_envs=2)
    with pytest.raises(error, match="seed"):
        env.reset(seed=seed)
    with pytest.raises(error, match="seed"):
        vec.reset(seed=seed)
    with pytest.raises(error, match=r"seed\[1\]"):
        vec.reset(seed=[0, seed])
    env.close()
    vec.close()


@pytest.mark.parametrize("key,value", [
    ("num_envs", 0), ("num_envs", 2.0), ("num_envs", True), ("num_envs", "2"),
    ("num_envs", 10**9), ("max_episode_steps", 0), ("max_episode_steps", -1),
    ("max_episode_steps", 1.5), ("max_episode_steps", "10"), ("max_episode_steps", True),
    ("max_episode_steps", 10**15)])
def test_vector_sizes_are_checked(key, value):
    kwargs = {"num_envs": 2, key: value}
    with pytest.raises(ValueError, match=f"{key} must be an int in"):
        _vector(**kwargs)


def test_vector_sizes_accept_numpy_ints():
    vec = _vector(num_envs=np.int64(2), max_episode_steps=np.int32(5))
    assert vec.num_envs == 2 and vec.max_episode_steps == 5
    vec.close()
