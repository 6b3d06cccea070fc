"""Observations are proprioceptive (+ tactile) only, scaled as documented, and laid out in order."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401
from softhand_env.envs.observation import (
    ANGLE_SCALE,
    DN_SCALE,
    DT_SCALE,
    OBS_BOUND,
    TORQUE_SCALE,
    VELOCITY_SCALE,
    ObservationLayout,
)
from softhand_env.physics.model import NQ, TH_1, TH_OBJ, X_OBJ, Y_OBJ

MODES = ["proprio", "proprio_tactile"]


def _moved_state(env, seed):
    """A mid-episode state (object displaced and rotated, fingers moving)."""
    env.reset(seed=seed)
    for _ in range(15):
        env.step(np.array([0.8, -0.8], dtype=np.float32))
    return env.physics.get_state(), env.config.grasp_setpoint + np.radians([3.0, -3.0])


@pytest.mark.parametrize("obs_mode", MODES)
def test_observation_ignores_object_state(obs_mode):
    env = gym.make("SoftHandPose-v0", obs_mode=obs_mode).unwrapped
    y, u = _moved_state(env, 0)
    assert abs(y[X_OBJ]) > 1e-4 and abs(y[TH_OBJ]) > 1e-3  # the object did move
    ref = env.observation_from_state(y, u)
    rng = np.random.default_rng(0)
    for _ in range(20):
        z = y.copy()
        # object pose and object velocities: anything, finger state unchanged
        z[[X_OBJ, Y_OBJ, TH_OBJ]] = rng.uniform(-1, 1, 3)
        z[[NQ + X_OBJ, NQ + Y_OBJ, NQ + TH_OBJ]] = rng.uniform(-10, 10, 3)
        np.testing.assert_array_equal(env.observation_from_state(z, u), ref)
    # the function does read the finger state (the test above can fail)
    z = y.copy()
    z[TH_1] += 0.01
    assert not np.array_equal(env.observation_from_state(z, u), ref)


@pytest.mark.parametrize("obs_mode", MODES)
def test_env_observation_is_the_state_function(obs_mode):
    env = gym.make("SoftHandReorient-v0", obs_mode=obs_mode, history_len=2).unwrapped
    obs, info = env.reset(seed=1)
    frame = env.config.layout.frame_size
    for _ in range(5):
        obs, _, _, _, info = env.step(np.array([0.3, 0.1], dtype=np.float32))
    expected = env.observation_from_state(env.physics.get_state(), info["setpoint"])
    np.testing.assert_array_equal(obs[:frame], expected)
    # goal last, scaled by 30 deg
    assert obs[-1] == pytest.approx(info["goal"][0] / ANGLE_SCALE, rel=1e-6)
    assert obs.shape == (2 * frame + 1,) and obs.dtype == np.float32


def test_frame_entries_and_scaling():
    env = gym.make("SoftHand-v0", obs_mode="proprio_tactile").unwrapped
    y, u = _moved_state(env, 2)
    y[NQ + TH_1] = 0.7  # a joint velocity to see its scale
    obs = env.observation_from_state(y, u).astype(np.float64)
    prm = env.physics.params
    tau = -prm.Kp * (y[3:5] - u) - prm.Kd * y[NQ + 3 : NQ + 5] - prm.Ki * y[18:20]
    expected = np.concatenate([
        y[3:5] / ANGLE_SCALE,
        y[NQ + 3 : NQ + 5] / VELOCITY_SCALE,
        u / ANGLE_SCALE,
        tau / TORQUE_SCALE,
        y[5:7] / DN_SCALE,
        y[7:9] / DT_SCALE,
    ])
    # float32 rounding of O(1) values: relative 6e-8; 1e-6 leaves margin
    np.testing.assert_allclose(obs, expected, rtol=1e-6, atol=1e-7)
    assert ANGLE_SCALE == pytest.approx(math.radians(30))
    # tactile entries are O(1) in a normal grasp: d_n about 7 mm -> about 0.7
    _, info = env.reset(seed=0)
    assert 0.5 < info["deformation"][0] / DN_SCALE < 0.9


def test_layout_names_and_sizes():
    lay = ObservationLayout("proprio_tactile", 3, ("x", "theta"))
    assert lay.frame_size == 12 and lay.size == 38
    assert lay.names[:3] == ("theta_1", "theta_2", "omega_1")
    assert lay.names[12] == "theta_1[t-1]" and lay.names[-2:] == ("goal_x", "goal_theta")
    env = gym.make("SoftHandPose-v0", history_len=3)
    assert env.observation_space.shape == (3 * 8 + 2,)
    assert env.observation_space.dtype == np.float32
    assert np.all(env.observation_space.high == OBS_BOUND)


def test_history_is_newest_first():
    env = gym.make("SoftHand-v0", history_len=3).unwrapped
    obs0, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs0[:8], obs0[8:16])
    np.testing.assert_array_equal(obs0[:8], obs0[16:24])
    obs1, *_ = env.step(np.array([1.0, 0.0], dtype=np.float32))
    obs2, *_ = env.step(np.array([1.0, 0.0], dtype=np.float32))
    np.testing.assert_array_equal(obs2[8:16], obs1[:8])
    np.testing.assert_array_equal(obs2[16:24], obs0[:8])


def test_observation_noise_is_seeded_and_zero_by_default():
    clean = gym.make("SoftHand-v0").unwrapped
    noisy = gym.make("SoftHand-v0", obs_noise=0.05).unwrapped
    o_clean, _ = clean.reset(seed=3)
    o_noisy, _ = noisy.reset(seed=3)
    d = o_noisy - o_clean
    assert 0 < np.abs(d).max() < 0.5  # 0.05 std over 8 entries: below 10 sigma
    o_again, _ = noisy.reset(seed=3)
    np.testing.assert_array_equal(o_again, o_noisy)
    # noise never reaches the physics: the state is the same with and without it
    a = np.array([0.5, -0.5], dtype=np.float32)
    clean.step(a)
    noisy.step(a)
    np.testing.assert_array_equal(clean.physics.get_state(), noisy.physics.get_state())


def test_frame_noise_is_the_float32_sum_clipped_to_the_bound():
    """The compiled noise step equals NumPy's float32 ``+=`` followed by the clip, bit for bit
    (also at and beyond the bound), and draws exactly ``size`` normals from the generator."""
    from softhand_env.envs.observation import add_frame_noise

    rng = np.random.default_rng(0)
    for k in range(500):
        frame = (rng.normal(size=12) * 10.0 ** rng.integers(-3, 3)).astype(np.float32)
        frame[k % 12] = OBS_BOUND * (-1) ** k - 1e-3 * (-1) ** k  # just inside the bound
        std = float(10.0 ** rng.integers(-3, 2))
        expected = frame.copy()
        expected += np.random.default_rng(k).normal(0.0, std, size=12)
        np.clip(expected, -OBS_BOUND, OBS_BOUND, out=expected)
        g = np.random.default_rng(k)
        add_frame_noise(frame, std, g)
        np.testing.assert_array_equal(frame.view(np.int32), expected.view(np.int32))
        # the generator advanced by exactly the 12 draws
        assert g.normal() == np.random.default_rng(k).normal(size=13)[12]
