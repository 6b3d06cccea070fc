"""The post-grasp cache: episodes are bit-identical with and without it, and its key holds
everything that determines the grasp phase."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from softhand_env.envs import start
from softhand_env.envs.start import grasp_cache, grasp_state
from softhand_env.physics.params import load_hand_params


def _single_rollout(env_id: str, steps: int, **kw):
    env = gym.make(env_id, max_episode_steps=15, **kw)
    rng = np.random.default_rng(7)
    out = [env.reset(seed=3)[0]]
    for _ in range(steps):
        obs, reward, term, trunc, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out += [obs, np.array([reward, term, trunc]), info["object_pose"], info["deformation"]]
        if term or trunc:
            out.append(env.reset()[0])
    return np.concatenate([np.ravel(np.asarray(a, dtype=np.float64)) for a in out])


def _vector_rollout(env_id: str, steps: int, **kw):
    env = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point",
                       max_episode_steps=15, **kw)
    rng = np.random.default_rng(7)
    out = [env.reset(seed=3)[0]]
    for _ in range(steps):
        obs, reward, term, trunc, info = env.step(rng.uniform(-1, 1, (3, 2)).astype(np.float32))
        out += [obs, reward, term, trunc, info["object_pose"], info["deformation"]]
    return np.concatenate([np.ravel(np.asarray(a, dtype=np.float64)) for a in out])


@pytest.mark.parametrize("env_id, kw", [
    ("SoftHandReorient-v0", {}), ("SoftHandReorient-v0", {"rand_mass": 0.1}),
    ("SoftHandReorient-v0", {"reset_noise_deg": 0.5}),
    ("SoftHandPose-v0", {"setpoint_latency": 2}),  # goals and latencies of the cached path
])
@pytest.mark.parametrize("rollout", [_single_rollout, _vector_rollout])
def test_same_seeds_give_identical_trajectories_with_and_without_the_cache(rollout, env_id, kw):
    start._CACHE.clear()
    with grasp_cache(True):
        cached = rollout(env_id, 40, **kw)
        again = rollout(env_id, 40, **kw)  # from a filled cache
    with grasp_cache(False):
        n = len(start._CACHE)
        fresh = rollout(env_id, 40, **kw)
        assert len(start._CACHE) == n  # nothing looked up or stored
    # 40 steps of 15-step episodes: three resets after the first
    np.testing.assert_array_equal(cached, fresh)
    np.testing.assert_array_equal(again, fresh)
    # only the nominal configuration is cached
    assert len(start._CACHE) == (1 if "rand_mass" not in kw and "reset_noise_deg" not in kw
                                 else 0)


def _variants():
    """Every HandParams field and every other argument of grasp_state, changed a little."""
    base = load_hand_params("paper_ch5")
    args = dict(setpoint=np.radians([6.0, 6.0]), n_substeps=2000, ch_limit=1e-3,
                dn_limit=0.5 * base.a, base_limit=1.05)
    for f in dataclasses.fields(base):
        value = getattr(base, f.name)
        if f.name == "cross_term":
            new = "printed"
        elif f.name == "integrator":
            new = "ros2"
        elif f.name == "M_deform":
            new = 1.01 * base.M_obj
        elif f.name == "g":
            new = 0.5 * value
        else:
            new = value * 1.001
        yield f.name, base.replace(**{f.name: new}), args
    yield "setpoint[0]", base, {**args, "setpoint": np.radians([6.1, 6.0])}
    yield "setpoint[1]", base, {**args, "setpoint": np.radians([6.0, 6.1])}
    yield "n_substeps", base, {**args, "n_substeps": 2001}
    yield "ch_limit", base, {**args, "ch_limit": 2e-3}
    yield "dn_limit", base, {**args, "dn_limit": 0.45 * base.a}
    yield "base_limit", base, {**args, "base_limit": 1.1}


def test_the_cache_key_holds_everything_that_determines_the_grasp():
    base = load_hand_params("paper_ch5")
    start._CACHE.clear()
    nominal_args = dict(setpoint=np.radians([6.0, 6.0]), n_substeps=2000, ch_limit=1e-3,
                        dn_limit=0.5 * base.a, base_limit=1.05)
    y0, _, _ = grasp_state(base, **nominal_args)
    n_changed = 0
    for name, params, args in _variants():
        before = len(start._CACHE)
        cached = grasp_state(params, **args)
        # a new entry (a miss), and the cached call equals a fresh simulation bit for bit
        assert len(start._CACHE) == min(before + 1, start._CACHE_SIZE), name
        fresh = grasp_state(params, **args, use_cache=False)
        np.testing.assert_array_equal(cached[0], fresh[0], err_msg=name)
        assert cached[1:] == fresh[1:], name
        n_changed += not np.array_equal(cached[0], y0)
    # the variants are not all equivalent: most of them change the post-grasp state
    assert n_changed >= 20
    # a hit returns a fresh copy
    y1, _, _ = grasp_state(base, **nominal_args)
    y1[:] = np.nan
    np.testing.assert_array_equal(grasp_state(base, **nominal_args)[0], y0)
