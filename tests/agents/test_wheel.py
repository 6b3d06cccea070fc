"""A regular install from the built wheel works outside the repository (``slow``, ~4 min):
configs and shipped models are package data, found from any working directory."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 900) -> str:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{cmd}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.mark.slow
def test_wheel_installs_trains_and_evaluates_shipped_models_outside_the_repo(tmp_path):
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    clean.update(OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    dist = tmp_path / "dist"
    run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation",
         "-q", "-w", str(dist)], cwd=tmp_path, env=clean)
    (wheel,) = dist.glob("softhand_env-*.whl")
    venv = tmp_path / "venv"
    run([sys.executable, "-m", "venv", str(venv)], cwd=tmp_path, env=clean)
    py = str(venv / "bin" / "python")
    run([py, "-m", "pip", "install", "-q", "torch==2.13.0"], cwd=tmp_path, env=clean)
    run([py, "-m", "pip", "install", "-q", f"{wheel}[train]"], cwd=tmp_path, env=clean)
    work = tmp_path / "elsewhere"
    work.mkdir()
    where = run([py, "-c", "import agents, softhand_env; print(agents.__file__); "
                 "print(softhand_env.__file__)"], cwd=work, env=clean)
    assert str(ROOT) not in where and str(venv) in where  # the installed copy, not the repo
    # train a few hundred steps from the installed hyper-parameter file
    run([py, "-m", "agents.train", "--env", "SoftHandTranslate-v0", "--n-timesteps", "256",
         "--eval-freq", "128", "--eval-episodes", "1", "--save-freq", "0", "--no-progress-bar",
         "--verbose", "0", "--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64",
         "n_epochs:1"], cwd=work, env=clean)
    trained = work / "logs" / "ppo" / "SoftHandTranslate-v0_1"
    assert (trained / "SoftHandTranslate-v0.zip").is_file()
    out = run([py, "-m", "agents.evaluate", "--model", str(trained), "--n-episodes", "1",
               "--no-plots"], cwd=work, env=clean)
    assert "success rate" in out
    assert "scored on them once" in out and (trained / "test_scores.yml").is_file()
    # a shipped model, by its env id (README: 100 % on the test goals)
    out = run([py, "-m", "agents.evaluate", "--model", "SoftHandReorient-v0", "--n-episodes",
               "3", "--no-plots"], cwd=work, env=clean)
    assert re.search(r"success rate \(1 deg\) +100\.0 % \(3/3, 95 % CI", out), out
    assert "shipped model: its test scores are documented" in out  # the package not written to
    # RL Zoo reads the installed hyper-parameter file unchanged
    conf = run([py, "-c", "from agents.runs.hyperparams import config_path; "
                "print(config_path('ppo', None))"], cwd=work, env=clean).strip()
    assert conf.startswith(str(venv)) and conf.endswith("agents/configs/ppo.yml")
    run([py, "-m", "rl_zoo3.train", "--gym-packages", "softhand_env", "--algo", "ppo", "--env",
         "SoftHandReorient-v0", "--conf-file", conf, "-n", "256", "--eval-freq", "-1",
         "--num-threads", "1", "-f", "zoo", "--hyperparams", "n_envs:2", "n_steps:64",
         "batch_size:64", "n_epochs:1"], cwd=work, env=clean)
    assert (work / "zoo" / "ppo" / "SoftHandReorient-v0_1" / "SoftHandReorient-v0.zip").is_file()
    shutil.rmtree(venv)  # over 1 GB: freed now, not at the end of the session
