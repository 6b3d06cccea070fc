"""Training CLI (agents.train): smoke runs, saved outputs, hyper-parameter parsing, error exits."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from agents import train
from agents.common import cli, env_factory
from agents.runs import hyperparams, loading
from agents.runs.zoo_dialect import zoo_yaml_load

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg"}
#: A tiny PPO run: 2 envs x 64 steps per update.
TINY_PPO = ["--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"]


def run_module(module: str, *args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", module, *args],
        cwd=cwd, env=ENV, capture_output=True, text=True, timeout=300,
    )


def test_training_cli_smoke_run_writes_model_stats_config_and_tensorboard(tmp_path):
    proc = run_module(
        "agents.train", "--env", "SoftHandTranslate-v0", "--algo", "ppo", "--seed", "3",
        "--n-timesteps", "256", "--eval-freq", "128", "--eval-episodes", "2",
        "--save-freq", "128", "--log-folder", str(tmp_path), "--no-progress-bar",
        "--env-kwargs", "ctrl_weight:0.02", "max_episode_steps:50", *TINY_PPO,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    run = tmp_path / "ppo" / "SoftHandTranslate-v0_1"
    env_id = "SoftHandTranslate-v0"
    # RL Zoo's run layout, plus the statistics as plain arrays
    for name in (f"{env_id}.zip", f"{env_id}/vecnormalize.pkl", f"{env_id}/vecnormalize.npz",
                 f"{env_id}/config.yml", f"{env_id}/args.yml", "evaluations.npz",
                 "best_model.zip", "best_model_vecnormalize.npz", "rl_model_128_steps.zip",
                 "rl_model_vecnormalize_128_steps.npz", "rl_model_vecnormalize_128_steps.pkl"):
        assert (run / name).is_file(), name
    assert list((run / "tb").rglob("events.out.tfevents.*"))
    text = (run / env_id / "config.yml").read_text()
    assert text.startswith("!!python/object/apply:collections.OrderedDict")  # as the zoo's
    hp = zoo_yaml_load(text)
    config = hp.pop("softhand")
    assert config["env_id"] == "SoftHandTranslate-v0" and config["seed"] == 3
    assert config["total_timesteps"] >= 256 and config["wall_time_s"] > 0
    # the sha256 of every model file of the run
    assert set(config["sha256"]) == {
        f"{env_id}.zip", f"{env_id}/vecnormalize.npz", f"{env_id}/vecnormalize.pkl",
        f"{env_id}/args.yml", f"{env_id}/manifest.yml", "best_model.zip",
        "best_model_vecnormalize.npz",
        "best_model_vecnormalize.pkl", *(f"rl_model_{n}_steps.zip" for n in (128, 256)),
        *(f"rl_model_vecnormalize_{n}_steps.{e}" for n in (128, 256) for e in ("npz", "pkl"))}
    args = zoo_yaml_load((run / env_id / "args.yml").read_text())
    assert args["algo"] == "ppo" and args["env"] == env_id and args["env_kwargs"] is None
    # YAML entry merged with the overrides
    assert hp["env_kwargs"]["ctrl_weight"] == 0.02
    assert hp["env_kwargs"]["x_tolerance_mm"] == 1.0
    assert hp["n_envs"] == 2 and hp["n_steps"] == 64
    assert config["overrides"]["env_kwargs"] == {"ctrl_weight": 0.02, "max_episode_steps": 50}
    assert {"stable-baselines3", "torch", "gymnasium"} <= set(config["versions"])
    assert config["eval"]["success_kwargs"] == {"x_tolerance_mm": 1.0}
    assert 0.0 <= config["best_validation"]["success_rate"] <= 1.0
    # the env signature is saved with the run and checked when the model is loaded
    sig = config["env_signature"]
    assert sig["env_id"] == "SoftHandTranslate-v0" and sig["observation_shape"] == [9]
    assert sig["action_mode"] == "delta" and sig["obs_mode"] == "proprio"
    # the saved run loads and acts on the env it was trained on
    policy = loading.ModelPolicy(run)
    env = env_factory.make_env("SoftHandTranslate-v0", policy.env_kwargs)
    policy.check_env(env)
    mismatch = r"obs_mode \(model 'proprio', env 'proprio_tactile'"
    with pytest.raises(cli.UserError, match=mismatch):
        policy.check_env(env_factory.make_env("SoftHandTranslate-v0",
                                         {**policy.env_kwargs, "obs_mode": "proprio_tactile"}))
    obs, _ = env.reset(seed=0)
    action, _ = policy.predict(obs)
    assert env.action_space.contains(np.asarray(action, dtype=np.float32))


def test_sac_in_process_run_and_next_run_directory(tmp_path):
    argv = ["--env", "SoftHandReorient-v0", "--algo", "sac", "--n-timesteps", "120",
            "--eval-freq", "0", "--save-freq", "0", "--log-folder", str(tmp_path),
            "--no-progress-bar", "--verbose", "0",
            "--hyperparams", "n_envs:1", "learning_starts:50", "batch_size:32"]
    first = train.main(argv)
    second = train.main(argv)
    assert first.name == "SoftHandReorient-v0_1" and second.name == "SoftHandReorient-v0_2"
    assert (second / "SoftHandReorient-v0.zip").is_file()
    assert not list(second.rglob("*vecnormalize*"))  # SAC entry: no normalisation
    # an off-policy zip loads safely too (train_freq and the replay buffer class rebuilt)
    policy = loading.ModelPolicy(second)
    env = env_factory.make_env("SoftHandReorient-v0", policy.env_kwargs)
    policy.check_env(env)
    obs = env.reset(seed=0)[0]
    action, _ = policy.predict(obs)
    assert env.action_space.contains(np.asarray(action, dtype=np.float32))
    from stable_baselines3 import SAC

    plain = SAC.load(second / "SoftHandReorient-v0.zip", buffer_size=1)  # our file: trusted
    np.testing.assert_array_equal(action, plain.predict(obs, deterministic=True)[0])


def test_training_stops_once_validation_success_reaches_the_threshold(tmp_path, monkeypatch):
    real = train.summarize

    def perfect(*args, **kwargs):  # every validation reports 100 %
        return {**real(*args, **kwargs), "success_rate": 1.0}

    monkeypatch.setattr(train, "summarize", perfect)
    run = train.main(["--env", "SoftHandReorient-v0", "--n-timesteps", "4096",
                      "--eval-freq", "64", "--eval-episodes", "1", "--stop-success", "0.9",
                      "--save-freq", "0", "--log-folder", str(tmp_path), "--no-progress-bar",
                      "--verbose", "0", "--hyperparams", "n_envs:2", "n_steps:32",
                      "batch_size:32", "n_epochs:1"])
    record = loading.ModelPolicy(run).run.record
    assert record["stopped_on_success_at"] == 64  # the first validation, not 4096 steps
    assert record["total_timesteps"] == 64 and record["eval"]["stop_success"] == 0.9


def test_fit_threads_apply_to_the_update_and_the_rollouts_keep_torch_threads(tmp_path,
                                                                             monkeypatch):
    from stable_baselines3 import PPO

    seen: dict[str, set[int]] = {"train": set(), "step": set()}
    real_train, real_step = PPO.train, train.HeldOutEvalCallback._on_step

    def spy_train(self):
        seen["train"].add(torch.get_num_threads())
        return real_train(self)

    def spy_step(self):  # called after every env step of the rollouts
        seen["step"].add(torch.get_num_threads())
        return real_step(self)

    monkeypatch.setattr(PPO, "train", spy_train)
    monkeypatch.setattr(train.HeldOutEvalCallback, "_on_step", spy_step)
    before = torch.get_num_threads()
    run = train.main(["--env", "SoftHandReorient-v0", "--n-timesteps", "128", "--eval-freq",
                      "0", "--save-freq", "0", "--log-folder", str(tmp_path),
                      "--no-progress-bar", "--verbose", "0", "--torch-threads", "1",
                      "--fit-threads", "2", *TINY_PPO])
    assert seen == {"train": {2}, "step": {1}}
    record = loading.ModelPolicy(run).run.record
    assert record["torch_threads"] == 1 and record["fit_threads"] == 2
    assert torch.get_num_threads() == 1  # the rollout count once learn() has returned
    torch.set_num_threads(before)


def test_training_can_start_from_a_saved_model_of_another_env_id(tmp_path):
    native = str(Path(hyperparams.config_path("ppo", None)).with_name("ppo_native.yml"))
    tiny = ["--n-timesteps", "64", "--eval-freq", "0", "--save-freq", "0", "--no-progress-bar",
            "--verbose", "0", "--log-folder", str(tmp_path), "--conf-file", native,
            "--hyperparams", "n_envs:2", "n_steps:32", "batch_size:32", "n_epochs:1"]
    first = train.main(["--env", "SoftHandReorient-v0", *tiny])
    # learning rate 0: the weights stay those of the start model (a Random-id run)
    second = train.main(["--env", "SoftHandReorientRandom-v0", "--trained-agent", str(first),
                         *tiny[:-5], "--hyperparams", "n_envs:2", "n_steps:32",
                         "batch_size:32", "n_epochs:1", "learning_rate:0.0"])
    a, b = loading.ModelPolicy(first), loading.ModelPolicy(second)
    for key, value in a.model.policy.state_dict().items():
        assert torch.equal(value, b.model.policy.state_dict()[key]), key
    record = b.run.record["trained_agent"]
    assert record["env_id"] == "SoftHandReorient-v0" and len(record["sha256"]) == 64
    with pytest.raises(cli.UserError, match="observation_space differs"):  # Pose: 10 entries
        train.main(["--env", "SoftHandReorient-v0", "--trained-agent", str(first), *tiny,
                    "--env-kwargs", "history_len:2"])


def test_hyperparams_anchor_merge_and_schedules(tmp_path):
    conf = tmp_path / "ppo.yml"
    conf.write_text(
        ".base: &base\n  policy: MlpPolicy\n  n_timesteps: 100\n  learning_rate: lin_1e-3\n"
        "  policy_kwargs: 'dict(net_arch=[8], activation_fn=nn.ReLU)'\n"
        "SoftHandTranslate-v0:\n  <<: *base\n  n_envs: 2\n"
    )
    hp = hyperparams.load_hyperparams("ppo", "SoftHandTranslate-v0", str(conf))
    assert hp["n_envs"] == 2 and hp["env_kwargs"] == {} and hp["normalize"] is False
    kwargs = hyperparams.algo_kwargs("ppo", hp)
    assert kwargs["learning_rate"](0.5) == pytest.approx(5e-4)
    import torch.nn as nn

    assert kwargs["policy_kwargs"]["activation_fn"] is nn.ReLU
    assert "n_envs" not in kwargs and "policy" not in kwargs


def test_shipped_yaml_entries_are_valid():
    for algo in ("ppo",):
        data = yaml.safe_load(hyperparams.config_path(algo, None).read_text())
        for env_id in ("SoftHandTranslate-v0", "SoftHandReorient-v0", "SoftHandPose-v0"):
            hp = hyperparams.load_hyperparams(algo, env_id)
            hyperparams.algo_kwargs(algo, hp)
            env_factory.make_env(env_id, hp["env_kwargs"], hp.get("env_wrapper")).close()
        assert all(k.startswith(".") or k.startswith("SoftHand") for k in data)


def test_goal_seeds_replay_the_same_goals_after_rewind():
    env = env_factory.GoalSeeds(env_factory.make_env("SoftHandPose-v0"), [7, 8])
    goals = [env.reset()[1]["goal"] for _ in range(3)]
    env.rewind()
    again = env.reset()[1]["goal"]
    np.testing.assert_array_equal(goals[0], goals[2])
    np.testing.assert_array_equal(goals[0], again)
    assert not np.array_equal(goals[0], goals[1])


def _play_validation(env, eval_seed):
    """(goal, success, final pose) of each validation episode, in goal order, under a policy
    that acts on each observation row alone (so batching cannot change an action)."""
    from stable_baselines3.common.evaluation import evaluate_policy

    from agents.sb3.training import rewind_validation

    class RowPolicy:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.clip(0.8 * np.sin(3.0 * obs[:, :2] + 1.0), -1, 1), state

    done_infos = []

    def keep(locals_, globals_):
        if locals_["done"]:
            done_infos.append(locals_["info"])

    rewind_validation(env, eval_seed)
    evaluate_policy(RowPolicy(), env, n_eval_episodes=env.num_envs if env.num_envs > 1 else 3,
                    deterministic=True, callback=keep)
    rows = [(tuple(i["goal"]), bool(i["is_success"]), tuple(i["object_pose"]))
            for i in done_infos]
    return sorted(rows)


def test_native_validation_plays_the_single_env_goal_set_with_the_same_outcomes():
    from agents.common.metrics import success_kwargs
    from agents.runs.records import EvalSettings
    from agents.sb3.native_vec_env import NativeVecEnv
    from agents.sb3.training import make_validation_env

    env_id, kwargs = "SoftHandPoseRandom-v1", {"max_episode_steps": 30, "control_dt": 0.04}
    ev = EvalSettings(eval_freq=1, n_eval_episodes=3, eval_seed=5000,
                      success_kwargs=success_kwargs(env_id), stop_success=None)
    native = make_validation_env(env_id, kwargs, None, "native", ev)
    single = make_validation_env(env_id, kwargs, None, "dummy", ev)
    assert isinstance(native.unwrapped, NativeVecEnv) and native.num_envs == 3
    assert single.num_envs == 1
    first = _play_validation(native, ev.eval_seed)
    assert first == _play_validation(single, ev.eval_seed)  # bit for bit
    assert first == _play_validation(native, ev.eval_seed)  # rewound: the same goals again
    assert len({goal for goal, _, _ in first}) == 3
    native.close()
    single.close()


@pytest.mark.parametrize(
    "argv,fragment",
    [
        (["--env", "NoSuchEnv-v0"], "unknown env id"),
        (["--env", "SoftHand-v0"], "no entry for 'SoftHand-v0'"),
        (["--env", "SoftHandTranslate-v0", "--env-kwargs", "bogus_kwarg:1"], "bad env kwargs"),
        (["--env", "SoftHandTranslate-v0", "--env-kwargs", "max_delta_deg:-1"], "max_delta_deg"),
        (["--env", "SoftHandTranslate-v0", "--env-kwargs", "novalue"], "key:value"),
        (["--env", "SoftHandTranslate-v0", "--hyperparams", "not_a_ppo_key:1"], "no hyper-param"),
        (["--env", "SoftHandTranslate-v0", "--conf-file", "/nonexistent.yml"], "not found"),
        (["--env", "SoftHandTranslate-v0", "--stop-success", "0"], "--stop-success"),
        (["--env", "SoftHandTranslate-v0", "--fit-threads", "0"], "--fit-threads"),
        (["--env", "SoftHandTranslate-v0", "--critic-warmup", "-1"], "--critic-warmup"),
        (["--env", "SoftHandTranslate-v0", "--critic-warmup-lr", "0"], "--critic-warmup-lr"),
        (["--env", "SoftHandTranslate-v0", "--log-std", "nan"], "--log-std"),
        (["--env", "SoftHandTranslate-v0", "--algo", "sac", "--critic-warmup", "64"],
         "apply to a2c and ppo"),
    ],
)
def test_wrong_inputs_exit_2_with_one_line(tmp_path, capsys, argv, fragment):
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(train.main, [*argv, "--log-folder", str(tmp_path), "--no-progress-bar"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err
    assert not (tmp_path / "ppo").exists()  # nothing created for a rejected input


def test_missing_required_key_is_reported(tmp_path, capsys):
    conf = tmp_path / "ppo.yml"
    conf.write_text("SoftHandTranslate-v0:\n  policy: MlpPolicy\n")
    with pytest.raises(SystemExit):
        cli.run_cli(train.main, ["--env", "SoftHandTranslate-v0", "--conf-file", str(conf)])
    assert "lacks required key(s) n_timesteps" in capsys.readouterr().err


def test_error_exit_in_a_subprocess_has_no_traceback(tmp_path):
    proc = run_module("agents.train", "--env", "SoftHandNope-v0", "--log-folder", str(tmp_path))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().count("\n") == 0 and "unknown env id" in proc.stderr


# ---------------------------------------------------------------- residual Pose wrapper
def _pose_env(steps: int = 400):
    from agents.scripted import ABSOLUTE_RAD

    return env_factory.make_env("SoftHandPose-v0", {**ABSOLUTE_RAD, "max_episode_steps": steps})


def test_loop_plan_has_bounded_steps_loops_then_translation():
    from agents.scripted.loop_plan import LoopPlanPolicy

    plan = LoopPlanPolicy.from_env(_pose_env())
    corners = plan.corners(5.0, -6.0)
    # residual roll -6 - 0.77 * 5 = -9.85 deg -> ceil(9.85 / (0.29 * 12)) = 3 equal loops
    assert len(corners) == 1 + 3 * 4 + 1
    sp = np.degrees(plan.plan(5.0, -6.0))
    assert np.max(np.abs(np.diff(sp, axis=0))) <= 1.0 + 1e-9
    np.testing.assert_allclose(sp[0], [6.0, 6.0])
    np.testing.assert_allclose(sp[-1], [6.0 - 5.0 / 1.34, 6.0 + 5.0 / 1.34])
    # a negative roll needs loops with b = 9.85 / (0.29 * 3) = +11.3 deg, squeezed open by 4 deg
    phi = (sp[:, 0] - sp[:, 1]) / 2
    assert np.max(phi) == pytest.approx(9.85 / (0.29 * 3))
    assert np.min(sp.sum(axis=1)) == pytest.approx(2 * (6.0 - 4.0))
    # no residual (theta* on the coupled line): straight translation only
    assert len(plan.corners(5.0, 0.77 * 5.0)) == 2


def test_residual_wrapper_with_zero_actions_replays_the_plan():
    from agents.scripted.loop_plan import LoopPlanPolicy
    from agents.wrappers.residual import ResidualWrapper

    raw, wrapped = _pose_env(60), ResidualWrapper(_pose_env(60))
    plan = LoopPlanPolicy.from_env(raw)
    obs, info = raw.reset(seed=11)
    wobs, winfo = wrapped.reset(seed=11)
    assert wobs.shape == wrapped.observation_space.shape == (raw.observation_space.shape[0] + 5,)
    np.testing.assert_array_equal(wobs[: obs.size], obs)
    state, start = None, np.array([True])
    while True:
        action, state = plan.predict(obs, state, start)
        start = np.array([False])
        obs, _, term, trunc, info = raw.step(action)
        wobs, _, wterm, wtrunc, winfo = wrapped.step(np.zeros(2))
        np.testing.assert_array_equal(info["object_pose"], winfo["object_pose"])
        assert (term, trunc) == (wterm, wtrunc)
        if term or trunc:
            break
    assert wobs[-1] == 0.0 and np.all(wobs[-5:-3] == 0.0)  # time up, offset untouched


def test_residual_wrapper_offsets_are_bounded_and_it_needs_absolute_actions():
    from agents.wrappers.residual import ResidualWrapper

    wrapped = ResidualWrapper(_pose_env(30), delta_deg=0.5, max_offset_deg=2.0)
    wrapped.reset(seed=0)
    for _ in range(10):
        obs, *_ = wrapped.step(np.array([1.0, -1.0]))
    np.testing.assert_allclose(obs[-5:-3], [1.0, -1.0])  # 2 deg cap reached after 4 steps
    with pytest.raises(ValueError, match="absolute"):
        ResidualWrapper(env_factory.make_env("SoftHandPose-v0"))
