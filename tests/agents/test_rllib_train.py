"""agents.rllib_train: RLlib PPO exported as an SB3 run acts as the RLModule; CLI errors; a short
training on a local Ray evaluated through agents.evaluate (slow)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import yaml

from agents import evaluate, rllib_train
from agents.common.cli import run_cli
from agents.common.env_factory import make_env
from agents.rllib.settings import ppo_settings
from agents.runs.hyperparams import load_hyperparams
from agents.runs.loading import ModelPolicy

ENV = "SoftHandReorient-v0"


def _rllib():
    return pytest.importorskip("ray.rllib.algorithms.ppo", reason="needs softhand-env[rllib]")


def _observations(n: int, seed: int) -> np.ndarray:
    """Observations of random play (n, obs_dim), plus rows far outside the statistics."""
    hp = load_hyperparams("ppo", ENV)
    env = make_env(ENV, hp["env_kwargs"])
    rng = np.random.default_rng(seed)
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    rows = []
    for _ in range(n):
        rows.append(obs)
        obs, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            obs, _ = env.reset()
    env.close()
    far = rng.normal(0.0, 50.0, size=(8, len(rows[0]))).astype(np.float32)  # clipped at 10
    return np.concatenate([np.asarray(rows, dtype=np.float32), far])


def test_exported_sb3_policy_acts_as_the_rlmodule(tmp_path):
    _rllib()
    import torch
    from ray.rllib.connectors.env_to_module import MeanStdFilter as FilterConnector
    from ray.rllib.core.columns import Columns
    from ray.rllib.utils.filter import MeanStdFilter

    from agents.rllib.algorithm import Sampling, ppo_config
    from agents.rllib.export import write_run

    hp = load_hyperparams("ppo", ENV)
    settings = ppo_settings(hp)
    config = ppo_config(settings, Sampling(ENV, hp["env_kwargs"], None, 0, 1, 0))
    env = make_env(ENV, hp["env_kwargs"])
    spec = config.get_default_rl_module_spec()
    spec.observation_space, spec.action_space = env.observation_space, env.action_space
    spec.model_config = config.model_config
    module = spec.build()
    env.close()
    torch.manual_seed(0)
    with torch.no_grad():  # weights unlike any initialisation: means beyond the bounds too
        for p in module.parameters():
            p.copy_(torch.randn_like(p) * 0.5)
    weights = {k: v.detach().numpy() for k, v in module.state_dict().items()}
    obs_filter = MeanStdFilter((len(env.observation_space.low),), clip=10.0)
    for row in _observations(300, seed=1):
        obs_filter(row, update=True)
    state = FilterConnector._get_state_from_filters({None: obs_filter})

    args = rllib_train.parse_args(["--env", ENV, "--num-env-runners", "0",
                                   "--stop-timesteps", "1000", "--out", str(tmp_path)])
    run = rllib_train.run_config(args, settings, hp)
    run_dir = tmp_path / "ppo" / f"{ENV}_1"
    write_run(run_dir, run, weights, state, 1000)

    obs = _observations(200, seed=7)
    normed = obs_filter(obs.copy(), update=False)  # RLlib's env-to-module step
    with torch.no_grad():
        out = module.forward_inference({Columns.OBS: torch.as_tensor(normed)})
        dist = module.get_inference_action_dist_cls().from_logits(out[Columns.ACTION_DIST_INPUTS])
        mean = dist.to_deterministic().sample().numpy()
        values = module.compute_values({Columns.OBS: torch.as_tensor(normed)}).numpy()
    space = spec.action_space
    rllib_actions = np.clip(mean, space.low, space.high)  # clip_actions=True, no squashing
    assert np.any(np.abs(mean) > 1.0)  # the clip is exercised

    policy = ModelPolicy(run_dir)  # checksums, manifest, weights_only, the .npz statistics
    sb3_actions, _ = policy.predict(obs, deterministic=True)
    assert sb3_actions.shape == rllib_actions.shape == (len(obs), 2)
    assert np.max(np.abs(sb3_actions - rllib_actions)) <= 1e-6
    np.testing.assert_allclose(policy.normalize(obs), normed, rtol=0, atol=1e-6)
    with torch.no_grad():
        sb3_values = policy.model.policy.predict_values(
            torch.as_tensor(policy.normalize(obs))).numpy()[:, 0]
    np.testing.assert_allclose(sb3_values, values, rtol=0, atol=1e-5)
    from agents.runs.zoo_dialect import zoo_yaml_load

    saved = zoo_yaml_load((run_dir / ENV / "config.yml").read_text(), "config.yml")
    assert saved["normalize"]["norm_reward"] is False and saved["softhand"]["vec_env"] == "rllib"


@pytest.mark.parametrize("argv, message", [
    (["--env", ENV, "--num-env-runners", "-1", "--stop-timesteps", "10"], "--num-env-runners"),
    (["--env", ENV, "--num-env-runners", "1", "--stop-timesteps", "0"], "--stop-timesteps"),
    (["--env", ENV, "--num-env-runners", "1", "--stop-timesteps", "9", "--envs-per-runner",
      "0"], "--envs-per-runner"),
    (["--env", ENV, "--num-env-runners", "1"], "--stop-timesteps"),
    (["--env", ENV, "--num-env-runners", "1", "--stop-timesteps", "9", "--address", " "],
     "--address"),
])
def test_bad_arguments_are_one_line_and_exit_2(capsys, tmp_path, argv, message):
    with pytest.raises(SystemExit) as exc:
        run_cli(rllib_train.main, [*argv, "--out", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0], err
    assert not any(tmp_path.iterdir())


def test_missing_rllib_is_one_line_and_exit_2(monkeypatch, capsys, tmp_path):
    for name in [m for m in sys.modules if m == "ray" or m.startswith("ray.")] + ["ray"]:
        monkeypatch.setitem(sys.modules, name, None)  # `import ray...` raises ImportError
    with pytest.raises(SystemExit) as exc:
        run_cli(rllib_train.main, ["--env", ENV, "--num-env-runners", "1",
                                   "--stop-timesteps", "10", "--out", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: agents.rllib_train needs Ray RLlib"), err
    assert "softhand-env[rllib]" in err[0]
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_trained_on_local_ray_and_evaluated(tmp_path):
    _rllib()
    import ray

    assert not ray.is_initialized()
    run_dir = rllib_train.main(["--env", ENV, "--num-env-runners", "1", "--envs-per-runner",
                                "2", "--stop-timesteps", "8192", "--seed", "3",
                                "--out", str(tmp_path / "logs")])
    assert not ray.is_initialized()  # the Ray it started is shut down
    assert run_dir == tmp_path / "logs" / "ppo" / f"{ENV}_1"
    from agents.runs.zoo_dialect import zoo_yaml_load

    record = zoo_yaml_load((run_dir / ENV / "config.yml").read_text(), "config.yml")["softhand"]
    assert record["trainer"] == "rllib" and record["iterations"] >= 2
    assert record["total_timesteps"] >= 8192 and record["env_steps_per_s"] > 0
    assert record["ray"]["num_env_runners"] == 1 and record["ray"]["cluster_cpus"] == 1
    out = tmp_path / "eval"
    evaluate.main(["--model", str(run_dir), "--n-episodes", "3", "--seed", "5000",
                   "--no-plots", "--out", str(out)])
    results = yaml.safe_load((out / "results.yml").read_text())
    assert results["summary"]["n_episodes"] == len(results["episodes"]) == 3
    assert results["benchmark"] is True and results["policy"] == str(run_dir)
