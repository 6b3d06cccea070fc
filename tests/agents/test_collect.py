"""agents.collect: Minari datasets of a policy's episodes (round trip, replay, errors, Ray)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from agents import collect
from agents.common.cli import UserError, run_cli
from agents.common.env_factory import make_env
from agents.offline import collection

minari = pytest.importorskip("minari")


@pytest.fixture
def datasets(tmp_path, monkeypatch):
    """A fresh MINARI_DATASETS_PATH."""
    root = tmp_path / "datasets"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return root


def _collect(env, policy, n, dataset_id, *extra):
    return collect.main(["--env", env, "--policy", policy, "--episodes", str(n),
                         "--dataset-id", dataset_id, *extra])[0]


def _replay_matches(dataset):
    """Every episode of ``dataset`` replayed from its seed with its actions in the recovered
    env gives the stored observations, rewards, ends and infos, bit for bit."""
    env = dataset.recover_environment()
    metas = list(dataset.storage.get_episode_metadata(range(dataset.total_episodes)))
    for ep, meta in zip(dataset.iterate_episodes(), metas, strict=True):
        obs, info = env.reset(seed=int(meta["seed"]))
        np.testing.assert_array_equal(obs, ep.observations[0])
        np.testing.assert_array_equal(info["object_pose"], ep.infos["object_pose"][0])
        for t, action in enumerate(ep.actions):
            obs, reward, term, trunc, info = env.step(action)
            np.testing.assert_array_equal(obs, ep.observations[t + 1])
            assert reward == ep.rewards[t]
            assert (term, trunc) == (ep.terminations[t], ep.truncations[t])
            np.testing.assert_array_equal(env.unwrapped.physics.object_velocity,
                                          ep.infos["object_velocity"][t + 1])
            for key in ("object_pose", "goal", "deformation", "friction_ratio"):
                np.testing.assert_array_equal(info[key], ep.infos[key][t + 1], err_msg=key)
            assert info["is_success"] == ep.infos["is_success"][t + 1]
            reason = ep.infos["termination_reason"][t + 1]
            reason = reason.decode() if isinstance(reason, bytes) else reason
            assert reason == (info["termination_reason"] or "")
        assert ep.terminations[-1] or ep.truncations[-1]
        assert bool(meta["success"]) == bool(ep.infos["is_success"][-1])
    env.close()


@pytest.mark.parametrize("policy, kind", [
    ("SoftHandPose-v0", "expert"),      # a shipped model with its time-feature wrapper
    ("SoftHandPose-v0_residual", "residual"),  # its residual wrapper (keywords) rebuilt
    ("loop-plan", "loop-plan"),         # a scripted policy (absolute set-points)
    ("random", "random"),
])
def test_dataset_round_trip_and_replay(datasets, policy, kind):
    dataset_id = f"softhand/pose/{kind}-v0"
    _collect("SoftHandPose-v0", policy, 2, dataset_id)
    dataset = minari.load_dataset(dataset_id)
    assert (datasets / dataset_id).is_dir()
    assert dataset.total_episodes == 2
    policy_obj, env_id, kwargs, wrapper, _ = collection.build_source(
        collection.CollectSource(policy, "SoftHandPose-v0"))
    env = make_env(env_id, kwargs, wrapper)
    assert dataset.observation_space == env.observation_space
    assert dataset.action_space == env.action_space
    env.close()
    for recovered in (dataset.recover_environment(), dataset.recover_environment(eval_env=True)):
        assert recovered.observation_space == dataset.observation_space
        assert recovered.action_space == dataset.action_space
        recovered.close()
    meta = dataset.storage.metadata
    assert meta["policy"] == policy and meta["env_id"] == "SoftHandPose-v0"
    assert meta["env_version"] == 0 and meta["sensor_model"] == "ideal"
    assert meta["first_seed"] == 0 and meta["n_seeds"] == 2
    assert "softhand-env==" in meta["code_permalink"] and meta["author"]
    if kind == "expert":
        assert meta["test_success"]["success"] == 0.99  # the shipped results.yml
        assert meta["test_success"]["first_seed"] == 10000
    elif kind == "residual":
        assert meta["test_success"]["success"] == 0.94
    else:
        assert meta["test_success"] is None
    seeds = [m["seed"] for m in dataset.storage.get_episode_metadata([0, 1])]
    assert seeds == [0, 1]
    _replay_matches(dataset)


def test_drawn_parameters_are_episode_metadata(datasets):
    _collect("SoftHandPoseRandom-v0", "random", 2, "softhand/pose-random/random-v0")
    dataset = minari.load_dataset("softhand/pose-random/random-v0")
    metas = list(dataset.storage.get_episode_metadata([0, 1]))
    env = dataset.recover_environment()
    for meta in metas:
        env.reset(seed=int(meta["seed"]))
        params = env.unwrapped.physics.params
        for field in collection.PARAM_FIELDS:
            assert meta[f"param_{field}"] == float(getattr(params, field)), field
        assert meta["setpoint_latency"] in (0, 1)
    assert metas[0]["param_M_obj"] != metas[1]["param_M_obj"]  # drawn per episode
    env.close()


def test_existing_id_is_kept_without_force(datasets):
    _collect("SoftHandTranslate-v0", "random", 1, "softhand/translate/random-v0")
    with pytest.raises(UserError, match="exists"):
        _collect("SoftHandTranslate-v0", "random", 3, "softhand/translate/random-v0")
    assert minari.load_dataset("softhand/translate/random-v0").total_episodes == 1
    _collect("SoftHandTranslate-v0", "random", 3, "softhand/translate/random-v0", "--force")
    assert minari.load_dataset("softhand/translate/random-v0").total_episodes == 3


@pytest.mark.parametrize("argv, message", [
    (["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2",
      "--dataset-id", "softhand/translate/random-v0"], "named softhand/pose/"),
    (["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2",
      "--dataset-id", "pose random"], "not a Minari dataset id"),
    (["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2", "--seed", "4999",
      "--dataset-id", "softhand/pose/random-v0"], "validation goals"),
    (["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2", "--seed", "10000",
      "--dataset-id", "softhand/pose/random-v0"], "validation goals|test goals"),
    (["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2", "--seed", "109999",
      "--dataset-id", "softhand/pose/random-v0"], "test goals"),
    (["--env", "SoftHandPose-v0", "--policy", "nosuch", "--episodes", "2",
      "--dataset-id", "softhand/pose/random-v0"], "neither a model path"),
    (["--env", "SoftHandTranslate-v0", "--policy", "SoftHandPose-v0", "--episodes", "2",
      "--dataset-id", "softhand/translate/expert-v0"], "trained on SoftHandPose-v0"),
    (["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "0",
      "--dataset-id", "softhand/pose/random-v0"], "--episodes"),
    (["--env", "SoftHandPose-v0", "--policy", "random"], "--episodes, --dataset-id needed"),
    (["--defaults", "--env", "SoftHandPose-v0"], "drop --env"),
    (["--env", "Nope-v0", "--policy", "random", "--episodes", "2",
      "--dataset-id", "softhand/pose/random-v0"], "unknown env id"),
])
def test_bad_input_is_one_line_and_exit_2_before_work(datasets, capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        run_cli(collect.main, argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    import re

    assert re.search(message, err[0]), err[0]
    assert not (datasets / "softhand").exists() or not any((datasets / "softhand").rglob(
        "data"))


def test_missing_ray_is_refused_before_work(datasets, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(SystemExit) as exc:
        run_cli(collect.main, ["--env", "SoftHandPose-v0", "--policy", "random", "--episodes",
                               "2", "--dataset-id", "softhand/pose/random-v0", "--ray"])
    assert exc.value.code == 2
    assert capsys.readouterr().err.startswith("error: --ray needs Ray")


def test_task_slugs_and_defaults():
    assert collection.task_slug("SoftHandPose-v0") == "pose"
    assert collection.task_slug("SoftHandPoseRandom-v0") == "pose-random"
    assert collection.task_slug("SoftHandTranslate-v1") == "translate-v1"
    ids = [d.dataset_id for d in collection.DEFAULT_DATASETS]
    assert len(set(ids)) == len(ids)
    assert {"softhand/pose/expert-v0", "softhand/pose/scripted-v0", "softhand/pose/loop-plan-v0",
            "softhand/pose/random-v0", "softhand/translate/expert-v0",
            "softhand/reorient/random-v0"} <= set(ids)
    for d in collection.DEFAULT_DATASETS:
        collection.check_dataset_id(d.dataset_id, d.env)
        collection.check_seeds(0, d.episodes)


def _arrays(dataset):
    out = []
    for ep in dataset.iterate_episodes():
        out.append((ep.observations, ep.actions, ep.rewards, ep.terminations, ep.truncations,
                    {k: np.asarray(v) for k, v in ep.infos.items()}))
    return out


@pytest.mark.parametrize("policy", ["SoftHandReorient-v0", "model-based"])
def test_two_ray_workers_write_the_serial_dataset(local_ray, datasets, policy):
    kind = "expert" if policy.startswith("SoftHand") else "scripted"
    argv = ["--env", "SoftHandReorient-v0", "--policy", policy, "--episodes", "3",
            "--seed", "20"]
    collect.main([*argv, "--dataset-id", f"softhand/reorient/{kind}-v0"])
    collect.main([*argv, "--dataset-id", f"softhand/reorient/{kind}-v1", "--ray",
                  "--ray-workers", "2"])
    serial = minari.load_dataset(f"softhand/reorient/{kind}-v0")
    sharded = minari.load_dataset(f"softhand/reorient/{kind}-v1")
    a, b = _arrays(serial), _arrays(sharded)
    assert len(a) == len(b) == 3
    for ea, eb in zip(a, b, strict=True):
        for xa, xb in zip(ea[:5], eb[:5], strict=True):
            np.testing.assert_array_equal(xa, xb)
        assert ea[5].keys() == eb[5].keys()
        for key in ea[5]:
            np.testing.assert_array_equal(ea[5][key], eb[5][key], err_msg=key)
    seeds = [m["seed"] for m in sharded.storage.get_episode_metadata(range(3))]
    assert seeds == [20, 21, 22]
