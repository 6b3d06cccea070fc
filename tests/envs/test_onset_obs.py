"""The grasp-onset entries (``onset_obs=True``): the joint angles of the grasp phase's first
state (fingertips touching the object, undeformed), read once per episode through the sensor
model, between the frames and the goal."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import SyncVectorEnv

import softhand_env  # noqa: F401  (registers the environments)
from softhand_env.envs.observation import ANGLE_SCALE, ONSET_NAMES
from softhand_env.envs.sensors import load_sensor_spec
from softhand_env.physics.model import initial_finger_angle

Q = math.radians(load_sensor_spec("realistic").encoder_resolution_deg)
S = math.radians(load_sensor_spec("realistic").encoder_noise_deg)


def _onset(obs, env):
    h = env.unwrapped.config.layout.history_size
    return obs[h:h + 2] * ANGLE_SCALE


def test_entries_sit_between_the_frames_and_the_goal_and_stay_for_the_episode():
    plain = gym.make("SoftHandPoseRandom-v0", history_len=2)
    env = gym.make("SoftHandPoseRandom-v0", history_len=2, onset_obs=True)
    layout = env.unwrapped.config.layout
    assert env.observation_space.shape[0] == plain.observation_space.shape[0] + 2
    assert layout.names[layout.history_size:layout.history_size + 2] == ONSET_NAMES
    assert layout.names[-2:] == ("goal_x", "goal_theta")
    actions = np.random.default_rng(0).uniform(-1, 1, (6, 2)).astype(np.float32)
    widths = set()
    for seed in (1, 2, 3):
        o_plain, _ = plain.reset(seed=seed)
        obs, _ = env.reset(seed=seed)
        # ideal sensors: the exact first-state angles of the episode's hand
        t0 = initial_finger_angle(env.unwrapped.physics.params)
        np.testing.assert_allclose(_onset(obs, env), [t0, t0], rtol=1e-6, atol=1e-9)
        widths.add(env.unwrapped.physics.params.W_obj)
        first = obs[layout.history_size:layout.history_size + 2].copy()
        for a in actions:
            # the other entries are those of the env without onset_obs (no draw added: ideal)
            h = layout.history_size
            np.testing.assert_array_equal(np.delete(obs, [h, h + 1]), o_plain)
            np.testing.assert_array_equal(obs[h:h + 2], first)
            obs, _, term, trunc, _ = env.step(a)
            o_plain, _, term_p, trunc_p, _ = plain.step(a)
            assert (term, trunc) == (term_p, trunc_p)
            if term or trunc:
                break
    assert len(widths) == 3  # randomised object widths: three different onsets read
    # the paper's hand: fingers parallel at contact, the onset angle is 0
    nominal = gym.make("SoftHandPose-v0", onset_obs=True)
    obs, _ = nominal.reset(seed=0)
    np.testing.assert_array_equal(_onset(obs, nominal), [0.0, 0.0])


def test_realistic_sensors_read_the_onset_through_the_encoder_model():
    env = gym.make("SoftHandPoseRandom-v1", onset_obs=True)
    errors = []
    for seed in range(40):
        obs, _ = env.reset(seed=seed)
        reading = _onset(obs, env).astype(np.float64)
        t0 = initial_finger_angle(env.unwrapped.physics.params)
        # a multiple of the encoder resolution (float32 scaled entries: 1e-6 relative)
        np.testing.assert_allclose(reading / Q, np.rint(reading / Q), atol=1e-4)
        errors.extend(reading - t0)
    errors = np.asarray(errors)
    # rounding (at most Q / 2) after N(0, S^2) noise: within Q / 2 + 5 S, spread about
    # sqrt(S^2 + Q^2 / 12)
    assert np.all(np.abs(errors) <= Q / 2 + 5 * S)
    assert 0.5 * math.hypot(S, Q / math.sqrt(12)) < errors.std() < 2 * math.hypot(
        S, Q / math.sqrt(12))


@pytest.mark.parametrize("env_id", ["SoftHandPoseRandom-v1", "SoftHandPoseRandom-v0"])
def test_vector_env_rows_equal_single_envs_with_onset(env_id):
    n, kwargs = 3, {"onset_obs": True, "history_len": 2, "max_episode_steps": 5}
    native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                          **kwargs)
    single = SyncVectorEnv([lambda: gym.make(env_id, **kwargs) for _ in range(n)])
    o1, _ = native.reset(seed=11)
    o2, _ = single.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    ends = 0
    for a in np.random.default_rng(1).uniform(-1, 1, (12, n, 2)).astype(np.float32):
        o1, _, te1, tr1, _ = native.step(a)
        o2, _, te2, tr2, _ = single.step(a)
        np.testing.assert_allclose(o1, o2, rtol=1e-6, atol=1e-7)  # float32 observations
        np.testing.assert_array_equal(te1 | tr1, te2 | tr2)
        ends += int((te1 | tr1).sum())
    assert ends >= n  # every env restarted at least once (its onset read again)
    native.close()
    single.close()


@pytest.mark.parametrize("num_envs", [None, 2])
def test_goal_dict_observation_keeps_the_onset_entries(num_envs):
    kwargs = {"onset_obs": True, "history_len": 2}
    if num_envs is None:
        box, d = (gym.make("SoftHandPoseRandom-v1", goal_obs=goal, **kwargs)
                  for goal in (False, True))
    else:
        box, d = (gym.make_vec("SoftHandPoseRandom-v1", num_envs=num_envs,
                               vectorization_mode="vector_entry_point", goal_obs=goal, **kwargs)
                  for goal in (False, True))
    o_box, _ = box.reset(seed=4)
    o_dict, _ = d.reset(seed=4)
    size = box.unwrapped.single_observation_space.shape[0] if num_envs else (
        box.observation_space.shape[0])
    # everything before the goal: the frames and the two onset entries
    assert o_dict["observation"].shape[-1] == size - 2
    np.testing.assert_array_equal(o_dict["observation"], o_box[..., : size - 2])
