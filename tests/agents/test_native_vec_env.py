"""SB3 VecEnv over the native vector env vs SB3's DummyVecEnv of single envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

import softhand_env  # noqa: F401
from agents.sb3.native_vec_env import NativeVecEnv, make_sb3_vec_env, split_infos

N = 4
ENV_ID = "SoftHandReorient-v0"
# randomisation + observation noise exercise every per-env random stream; a short time limit
# gives truncations, env 0 opening its fingers gives terminations
KWARGS = {"obs_mode": "proprio_tactile", "history_len": 2, "randomize": True,
          "max_episode_steps": 20}


def _actions(steps, seed=0):
    a = np.random.default_rng(seed).uniform(-1, 1, (steps, N, 2)).astype(np.float32)
    a[5:12, 0] = -1.0
    a[30:45, 1] = -1.0
    return a


def _assert_info_equal(a, b, where):
    assert sorted(a) == sorted(b), where
    for key, vb in b.items():
        va = a[key]
        if key == "episode":  # Monitor's statistics; "t" is wall time
            assert (va["r"], va["l"]) == (vb["r"], vb["l"]), where
        elif isinstance(vb, (str, type(None), bool, int)):
            assert va == vb and type(va) is type(vb), (where, key)
        else:
            # same kernel code per system: equal to round-off (in practice bit-equal)
            np.testing.assert_allclose(va, vb, rtol=1e-12, atol=1e-15, err_msg=f"{where} {key}")


def _pair(**kwargs):
    kw = {**KWARGS, **kwargs}
    dummy = DummyVecEnv([lambda: Monitor(gym.make(ENV_ID, **kw)) for _ in range(N)])
    native = NativeVecEnv(gym.make_vec(ENV_ID, num_envs=N,
                                       vectorization_mode="vector_entry_point", **kw))
    return dummy, native


@pytest.mark.parametrize("autoreset_mode", ["NextStep", "Disabled"])
def test_same_transitions_as_dummy_vec_env(autoreset_mode):
    dummy, native = _pair()
    if autoreset_mode == "Disabled":
        native = NativeVecEnv(gym.make_vec(ENV_ID, num_envs=N,
                                           vectorization_mode="vector_entry_point",
                                           autoreset_mode="Disabled", **KWARGS))
    assert dummy.seed(7) == native.seed(7)
    o1, o2 = dummy.reset(), native.reset()
    np.testing.assert_array_equal(o1, o2)
    for i in range(N):
        _assert_info_equal(native.reset_infos[i], dummy.reset_infos[i], f"reset {i}")
    terminated = truncated = 0
    for t, a in enumerate(_actions(80)):
        dummy.step_async(a)
        native.step_async(a)
        o1, r1, d1, i1 = dummy.step_wait()
        o2, r2, d2, i2 = native.step_wait()
        np.testing.assert_array_equal(o1, o2, err_msg=f"step {t}")
        np.testing.assert_allclose(r2, r1, rtol=1e-6, err_msg=f"step {t}")  # float32 buffers
        assert r2.dtype == r1.dtype
        np.testing.assert_array_equal(d1, d2)
        for i in range(N):
            _assert_info_equal(i2[i], i1[i], f"step {t} env {i}")
            if d1[i]:
                _assert_info_equal(native.reset_infos[i], dummy.reset_infos[i], f"reset {t} {i}")
                terminated += not i1[i]["TimeLimit.truncated"]
                truncated += i1[i]["TimeLimit.truncated"]
    # both kinds of episode end happened (terminal observations compared above)
    assert terminated >= 2 and truncated >= 4


def test_vecnormalize_episode_statistics_and_attributes():
    venv = make_sb3_vec_env(ENV_ID, N, seed=3, env_kwargs={"max_episode_steps": 10},
                            vec_env="native")
    assert isinstance(venv, NativeVecEnv)
    norm = VecNormalize(venv, gamma=0.99)
    norm.reset()
    episodes = 0
    for _ in range(25):
        _, _, dones, infos = norm.step(np.zeros((N, 2), dtype=np.float32))
        for done, info in zip(dones, infos, strict=True):
            if done:
                assert info["episode"]["l"] == 10
                episodes += 1
    assert episodes == 2 * N
    assert venv.get_attr("dt") == [0.02] * N
    dict_venv = make_sb3_vec_env(ENV_ID, 2, 0, {"privileged_obs": True}, "native")
    assert dict_venv.get_attr("dt") == [0.02] * 2  # through the Dict wrapper
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        dict_venv.get_attr("nope")
    assert norm.get_attr("num_envs", indices=[1]) == [N]
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * N
    assert venv.env_is_wrapped(Monitor) == [True] * N  # it reports Monitor's statistics
    with pytest.raises(ValueError, match="all 4 environments"):
        venv.set_attr("dt", 0.01, indices=[0])
    with pytest.raises(ValueError, match="only env_wrappers with a vector equivalent"):
        make_sb3_vec_env(ENV_ID, 2, 0, {}, "native",
                         env_wrapper=["gymnasium.wrappers.FrameStackObservation"])
    with pytest.raises(ValueError, match="vec_env must be one of"):
        make_sb3_vec_env(ENV_ID, 2, 0, {}, "ray")
    norm.close()


def test_images_one_per_env():
    venv = make_sb3_vec_env(ENV_ID, 2, 0, {"render_mode": "rgb_array", "render_width": 64,
                                           "render_height": 48}, "native")
    venv.reset()
    images = venv.get_images()
    assert venv.render_mode == "rgb_array" and [i.shape for i in images] == [(48, 64, 3)] * 2
    assert not np.array_equal(images[0], np.zeros_like(images[0]))


def test_split_infos_masks_and_scalars():
    infos = {"a": np.array([1.0, 2.0]), "_a": np.array([True, False]),
             "r": np.array([None, "success"], dtype=object), "_r": np.array([False, True]),
             "v": np.ones((2, 3)), "_v": np.array([True, True])}
    out = split_infos(infos, 2)
    assert out[0] == {"a": 1.0, "v": out[0]["v"]} and type(out[0]["a"]) is float
    assert out[1]["r"] == "success" and "a" not in out[1]
    np.testing.assert_array_equal(out[1]["v"], np.ones(3))


def test_split_infos_of_a_step_keeps_key_order_and_copies_rows():
    # every key in every environment (a step's info): the rows of all keys at once, in the
    # keys' order, arrays private (writing a row leaves the batched info as it was)
    v = np.arange(6.0).reshape(2, 3)
    infos = {"v": v, "_v": np.array([True, True]), "k": np.array([3, 4]),
             "_k": np.array([True, True]), "s": np.array([None, "slip"], dtype=object),
             "_s": np.array([True, True])}
    out = split_infos(infos, 2)
    assert [list(d) for d in out] == [["v", "k", "s"]] * 2
    assert out[1]["k"] == 4 and type(out[1]["k"]) is int and out[1]["s"] == "slip"
    out[0]["v"][0] = -1.0
    assert v[0, 0] == 0.0
    np.testing.assert_array_equal(out[1]["v"], [3.0, 4.0, 5.0])
    # a nested dict under a mask (SameStep's final_info) goes through the row-by-row path
    nested = {"final_info": {"x": np.array([0.0, 7.0]), "_x": np.array([False, True])},
              "_final_info": np.array([False, True]), "k": np.array([1, 2]),
              "_k": np.array([True, True])}
    out = split_infos(nested, 2)
    assert out[0] == {"k": 1} and out[1] == {"final_info": {"x": 7.0}, "k": 2}
    assert list(out[1]) == ["final_info", "k"]


def test_train_cli_runs_on_the_native_vec_env(tmp_path):
    from agents import train

    run = train.main([
        "--env", ENV_ID, "--algo", "ppo", "--n-timesteps", "256",
        "--save-freq", "0", "--log-folder", str(tmp_path), "--no-progress-bar", "--verbose", "0",
        "--env-kwargs", "max_episode_steps:50",
        "--hyperparams", "vec_env:native", "n_envs:4", "n_steps:64", "batch_size:128",
        "n_epochs:1", "--eval-freq", "128", "--eval-episodes", "2",
    ])
    assert (run / f"{ENV_ID}.zip").is_file() and (run / ENV_ID / "vecnormalize.npz").is_file()
    # the validation callback ran (its statistics synchronised with the native env's)
    assert (run / "best_model.zip").is_file()


def test_train_and_evaluate_an_asymmetric_agent_on_privileged_observations(tmp_path):
    from agents import evaluate, train

    run = train.main([
        "--env", ENV_ID, "--algo", "ppo", "--n-timesteps", "256", "--eval-freq", "0",
        "--save-freq", "0", "--log-folder", str(tmp_path), "--no-progress-bar", "--verbose", "0",
        "--env-kwargs", "max_episode_steps:30", "privileged_obs:true",
        "--hyperparams", "vec_env:native", "n_envs:4", "n_steps:64", "batch_size:128",
        "n_epochs:1", "policy:AsymmetricPolicy",
    ])
    # trained on 30-step episodes: evaluated on them on purpose (not the benchmark's 250)
    summary = evaluate.main(["--model", str(run), "--n-episodes", "2", "--no-plots",
                             "--out", str(tmp_path / "eval"), "--task-kwargs",
                             "max_episode_steps:30"])
    assert 0.0 <= summary["success_rate"] <= 1.0
