"""Model files: a model whose env version or observation/action layout differs from
the evaluation env is refused with a ``ValueError`` naming the differing field."""

from __future__ import annotations

import json
import re

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import SyncVectorEnv

import softhand_env
from softhand_env.envs.signature import (
    SIGNATURE_FIELDS,
    check_model_compatibility,
    env_signature,
    load_env_signature,
    save_env_signature,
    signature_path,
)


def test_signature_describes_the_env_the_same_way_for_every_kind_of_env():
    from stable_baselines3.common.env_util import make_vec_env

    kw = {"obs_mode": "proprio_tactile", "history_len": 2, "max_delta_deg": 2.0}
    sig = env_signature(gym.make("SoftHandPose-v0", **kw))
    assert tuple(sig) == SIGNATURE_FIELDS
    assert sig["env_id"] == "SoftHandPose-v0" and sig["version"] == softhand_env.__version__
    assert sig["task"] == "pose" and sig["obs_mode"] == "proprio_tactile"
    assert sig["history_len"] == 2 and sig["observation_shape"] == [2 * 12 + 2]
    assert sig["action_mode"] == "delta" and sig["normalize_action"] is True
    assert sig["max_delta_deg"] == pytest.approx(2.0) and sig["control_dt"] == pytest.approx(0.02)
    json.dumps(sig)  # JSON-able as it is
    others = [
        gym.make("SoftHandPose-v0", **kw).unwrapped,  # no spec: id from the task
        gym.make_vec("SoftHandPose-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     **kw),
        SyncVectorEnv([lambda: gym.make("SoftHandPose-v0", **kw)] * 2),
        make_vec_env("SoftHandPose-v0", n_envs=2, env_kwargs=kw),  # SB3 DummyVecEnv
    ]
    for env in others:
        check_model_compatibility(sig, env)
        assert env_signature(env) == sig


def test_signature_file_round_trip(tmp_path):
    env = gym.make("SoftHandReorient-v0", history_len=3)
    path = signature_path(tmp_path / "ppo" / "model.zip")
    assert path == tmp_path / "ppo" / "model.env.json"
    path.parent.mkdir()
    save_env_signature(env, path)
    assert load_env_signature(path) == env_signature(env)
    assert check_model_compatibility(str(path), env) == env_signature(env)
    with pytest.raises(ValueError, match="history_len"):
        check_model_compatibility(path, gym.make("SoftHandReorient-v0"))
    path.write_text("{not json")
    with pytest.raises(ValueError, match="cannot read env signature"):
        check_model_compatibility(path, env)


@pytest.mark.parametrize(
    "train_kwargs, eval_kwargs, fields",
    [
        ({"history_len": 2}, {}, ["history_len", "observation_shape"]),
        ({"obs_mode": "proprio_tactile"}, {}, ["obs_mode", "observation_shape"]),
        ({"action_mode": "absolute"}, {}, ["action_mode"]),
        ({"action_mode": "absolute", "normalize_action": False}, {"action_mode": "absolute"},
         ["normalize_action"]),
        ({"max_delta_deg": 2.0}, {}, ["max_delta_deg"]),
        ({"joint_range_deg": (-20.0, 20.0)}, {}, ["joint_range_deg"]),
        ({"control_dt": 0.01}, {}, ["control_dt"]),
    ],
)
def test_layout_mismatch_raises_naming_every_differing_field(train_kwargs, eval_kwargs, fields):
    saved = env_signature(gym.make("SoftHandReorient-v0", **train_kwargs))
    with pytest.raises(ValueError) as info:
        check_model_compatibility(saved, gym.make("SoftHandReorient-v0", **eval_kwargs))
    named = re.findall(r"(\w+) \(model", str(info.value))
    assert named == fields


@pytest.mark.parametrize("env_id", ["SoftHandPose-v1", "SoftHandPoseRandom-v1",
                                    "SoftHandPoseRandom-v0", "SoftHandPose-v0"])
def test_directly_constructed_env_signs_with_the_id_of_its_keywords(env_id):
    from softhand_env.envs import SoftHandEnv, registered_kwargs

    sig = env_signature(SoftHandEnv(**registered_kwargs(env_id)))
    assert sig == env_signature(gym.make(env_id))
    assert sig["env_id"] == env_id
    assert sig["sensor_model"] == ("realistic" if env_id.endswith("-v1") else "ideal")


def test_sensor_model_mismatch_is_refused_and_old_signatures_mean_ideal():
    saved = env_signature(gym.make("SoftHandPose-v0"))
    legacy = {k: v for k, v in saved.items() if k != "sensor_model"}  # saved before the field
    for model in (saved, legacy):
        check_model_compatibility(model, gym.make("SoftHandPose-v0"))
        with pytest.raises(ValueError) as info:
            check_model_compatibility(model, gym.make("SoftHandPose-v1"))
        assert re.findall(r"(\w+) \(model", str(info.value)) == ["env_id", "sensor_model"]
        assert "sensor_model (model 'ideal', env 'realistic')" in str(info.value)
        with pytest.raises(ValueError, match="sensor_model .*'ideal', env 'realistic'"):
            check_model_compatibility(model, gym.make("SoftHandPose-v0",
                                                      sensor_model="realistic"))
    with pytest.raises(ValueError, match="sensor_model .*'realistic', env 'ideal'"):
        check_model_compatibility(env_signature(gym.make("SoftHandPose-v1")),
                                  gym.make("SoftHandPose-v1", sensor_model="ideal"))
    # the per-episode calibration draws are not part of it (like hand randomisation)
    check_model_compatibility(env_signature(gym.make("SoftHandPose-v1")),
                              gym.make("SoftHandPose-v1", rand_sensors=True),
                              ignore=("env_id",))


def test_other_task_and_version_are_refused_unless_ignored():
    saved = env_signature(gym.make("SoftHandTranslate-v0"))
    with pytest.raises(ValueError, match=r"env_id .*task \(model 'translate', env 'reorient'\)"):
        check_model_compatibility(saved, gym.make("SoftHandReorient-v0"))
    old = {**saved, "version": "0.0.1"}
    env = gym.make("SoftHandTranslate-v0")
    with pytest.raises(ValueError, match=r"version \(model '0.0.1', env '"):
        check_model_compatibility(old, env)
    check_model_compatibility(old, env, ignore=("version",))
    # a signature from a newer/older schema: the unknown or missing field is named
    with pytest.raises(ValueError, match="frame_stack .*unknown"):
        check_model_compatibility({**saved, "frame_stack": 4}, env)
    partial = {k: v for k, v in saved.items() if k != "obs_mode"}
    with pytest.raises(ValueError, match="obs_mode .*missing"):
        check_model_compatibility(partial, env)


def test_sb3_model_carries_its_signature_through_save_and_load(tmp_path):
    from stable_baselines3 import PPO

    train_env = gym.make("SoftHandReorient-v0", history_len=2)
    model = PPO("MlpPolicy", train_env, n_steps=16, batch_size=16, device="cpu")
    model.env_signature = env_signature(train_env)  # saved in the zip with the model
    model.save(tmp_path / "model.zip")
    loaded = PPO.load(tmp_path / "model.zip", device="cpu")
    assert loaded.env_signature == model.env_signature
    check_model_compatibility(loaded, gym.make("SoftHandReorient-v0", history_len=2))
    with pytest.raises(ValueError) as info:
        check_model_compatibility(loaded, gym.make("SoftHandReorient-v0"))
    msg = str(info.value)
    assert "observation_space (model shape [17], env shape [9])" in msg
    assert "history_len (model 2, env 1)" in msg
    # a model saved without a signature: spaces are still checked, with a warning
    del loaded.env_signature
    with pytest.warns(UserWarning, match="no env signature"):
        check_model_compatibility(loaded, gym.make("SoftHandReorient-v0", history_len=2))
    with pytest.warns(UserWarning), pytest.raises(ValueError, match="observation_space"):
        check_model_compatibility(loaded, gym.make("SoftHandReorient-v0"))


def test_rejects_what_is_not_a_model_or_not_a_softhand_env():
    env = gym.make("SoftHandReorient-v0")
    with pytest.raises(ValueError, match="model_or_metadata"):
        check_model_compatibility(42, env)
    with pytest.raises(ValueError, match="not a softhand-env environment"):
        env_signature(gym.make("CartPole-v1"))
    obs = np.zeros(9, dtype=np.float32)
    assert env.observation_space.contains(obs)  # the shapes used above are the real ones
