"""RL Baselines3 Zoo both ways: rl_zoo3.train reads our hyper-parameter files unchanged and its
runs are read by agents.evaluate; rl_zoo3.enjoy plays the shipped models (laid out as zoo
runs); the zoo's Optuna optimisation runs on our configs with SQLite storage."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from agents import evaluate
from agents.common import cli
from agents.runs.hyperparams import config_path
from agents.runs.loading import MODELS_DIR

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
TINY = ["--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"]


def zoo(module: str, *args: str, cwd: Path, timeout: float = 600) -> str:
    proc = subprocess.run([sys.executable, "-m", f"rl_zoo3.{module}", "--gym-packages",
                           "softhand_env", "--num-threads", "1", *args],
                          cwd=cwd, env=ENV, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def test_zoo_trains_our_config_unchanged_and_agents_evaluate_reads_its_run(tmp_path, capsys):
    # the Pose entry: residual wrapper with keywords, policy_kwargs string, normalize mapping
    zoo("train", "--algo", "ppo", "--env", "SoftHandPose-v0", "--conf-file",
        str(config_path("ppo", None)), "-f", "logs", "-n", "256", "--eval-freq", "-1",
        "--save-freq", "-1", *TINY, cwd=tmp_path)
    run = tmp_path / "logs" / "ppo" / "SoftHandPose-v0_1"
    assert (run / "SoftHandPose-v0.zip").is_file()
    argv = ["--model", str(run), "--n-episodes", "1", "--no-plots", "--out", str(tmp_path / "o")]
    # the zoo stores the statistics as a pickle only: refused unless trusted
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(evaluate.main, argv)
    assert exc.value.code == 2 and "--trust-model" in capsys.readouterr().err
    summary = evaluate.main([*argv, "--trust-model"])
    assert summary["n_episodes"] == 1
    err = capsys.readouterr().err
    assert "records no sha256" in err and "no env_signature" in err  # a zoo run: warned


def _enjoy_success(env_id: str, n_steps: int, cwd: Path) -> tuple[float, int]:
    out = zoo("enjoy", "-f", str(MODELS_DIR), "--algo", "ppo", "--env", env_id, "--exp-id",
              "1", "-n", str(n_steps), "--no-render", cwd=cwd)
    rate = float(re.search(r"Success rate: ([\d.]+)%", out).group(1)) / 100
    episodes = int(re.search(r"(\d+) Episodes", out).group(1))
    return rate, episodes


@pytest.mark.slow
@pytest.mark.parametrize("env_id,floor,steps", [("SoftHandTranslate-v0", 0.95, 5000),
                                                ("SoftHandReorient-v0", 0.95, 5000),
                                                ("SoftHandPose-v0", 0.90, 8000)])
def test_zoo_enjoy_plays_the_shipped_models_as_well_as_agents_evaluate(tmp_path, env_id,
                                                                        floor, steps):
    """rl_zoo3.enjoy on the shipped runs (its own seeds, 20 episodes): the floors of the
    README table's tasks (measured with enjoy: 100 %, 100 % over ~100 episodes; Pose, the agent
    learned without the plan, 98.1 % over 160 episodes)."""
    rate, episodes = _enjoy_success(env_id, steps, tmp_path)
    assert episodes >= 19 and rate >= floor, (rate, episodes)


@pytest.mark.slow
def test_zoo_optuna_optimisation_with_sqlite_storage(tmp_path):
    import optuna

    storage = f"sqlite:///{tmp_path / 'study.db'}"
    zoo("train", "--algo", "ppo", "--env", "SoftHandTranslate-v0", "--conf-file",
        str(config_path("ppo", None)), "-f", "logs", "-n", "300", "--hyperparams", "n_envs:1",
        "-optimize", "--n-trials", "2", "--n-jobs", "1", "--sampler", "random", "--pruner",
        "none", "--n-startup-trials", "1", "--n-evaluations", "1", "--eval-episodes", "1",
        "--storage", storage, "--study-name", "smoke", "--no-optim-plots", cwd=tmp_path)
    study = optuna.load_study(study_name="smoke", storage=storage)
    assert [t.state.name for t in study.trials] == ["COMPLETE", "COMPLETE"]
    assert all(t.params and t.value is not None for t in study.trials)  # sampled, scored


def test_agents_do_not_import_rl_zoo3_in_process():
    """Importing rl_zoo3 replaces gymnasium's TimeLimit for every env of the process (it adds
    ``TimeLimit.truncated`` to infos); our CLIs read and write its formats without it."""
    code = ("import sys, agents.train, agents.evaluate, agents.demo; "
            "from agents.runs.hyperparams import algo_kwargs, load_hyperparams; "
            "algo_kwargs('ppo', {**load_hyperparams('ppo', 'SoftHandPose-v0'), "
            "'learning_rate': 'lin_1e-3'}); assert 'rl_zoo3' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], env=ENV, check=True, timeout=300)
