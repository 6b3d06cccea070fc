"""An interrupted training leaves a usable run: SIGINT or SIGTERM at any moment of ``learn()``
(mostly inside the numba kernel, where the time goes) stops training between steps; the final
zip, the best model and the checkpoints are evaluable and ``config.yml`` is finalised (outcome
with ``interrupted: true``, sha256 of every model file)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agents import evaluate
from agents.runs.loading import resolve_model
from agents.runs.model_files import sha256

ROOT = Path(__file__).resolve().parents[2]
ENV = "SoftHandTranslate-v0"


def _train_and_signal(log: Path, name: str, signum: int, delay_s: float,
                      vec_env: str, group: bool = False) -> Path:
    """Start a long training, send ``signum`` ``delay_s`` after the run directory exists (to
    its whole process group if ``group``, as Ctrl-C in a terminal does: the subproc workers
    get it too); returns the run directory once the process has ended (exit code 0
    asserted)."""
    cmd = [sys.executable, "-W", "ignore", "-m", "agents.train", "--env", ENV,
           "--n-timesteps", "10000000", "--hyperparams", "n_steps:64", "batch_size:64",
           "n_envs:2", "--eval-freq", "128", "--eval-episodes", "1", "--save-freq", "128",
           "--no-progress-bar", "--verbose", "0", "--vec-env", vec_env,
           "--log-folder", str(log), "--run-name", name]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": str(ROOT)},
                            start_new_session=group)
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            if line.startswith("run directory:"):
                break
        else:
            pytest.fail(f"no run directory: {proc.stderr.read() if proc.stderr else ''}")
        time.sleep(delay_s)
        if group:
            os.killpg(proc.pid, signum)
        else:
            proc.send_signal(signum)
        out, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err[-2000:]
    assert signal.Signals(signum).name in err, err[-2000:]
    return log / "ppo" / name


@pytest.mark.parametrize(
    "signum,delay_s,vec_env,group",
    [(signal.SIGINT, 0.0, "dummy", False),     # at once: while the first rollout starts
     pytest.param(signal.SIGTERM, 2.0, "dummy", False, marks=pytest.mark.slow),
     # inside the batched kernel of the native vector env
     pytest.param(signal.SIGINT, 4.0, "native", False, marks=pytest.mark.slow),
     # Ctrl-C in a terminal: the subproc workers get it too, and ignore it
     pytest.param(signal.SIGINT, 3.0, "subproc", True, marks=pytest.mark.slow)],
    ids=["sigint-at-once", "sigterm-2s", "sigint-4s-native", "sigint-group-3s-subproc"],
)
def test_interrupted_training_is_evaluable(tmp_path, signum, delay_s, vec_env, group):
    run = _train_and_signal(tmp_path / "logs", f"r{signum}_{vec_env}", signum, delay_s, vec_env,
                            group)
    record = resolve_model(run).record  # config.yml's record, checksums verified on load
    assert record["interrupted"] is True
    assert 0 < record["total_timesteps"] < 10_000_000
    digests = record["sha256"]
    assert digests[f"{ENV}.zip"] == sha256(run / f"{ENV}.zip")
    for name, digest in digests.items():  # every recorded file as it is on disk
        assert sha256(run / name) == digest, name
    zips = [run / f"{ENV}.zip", *sorted(run.glob("best_model.zip")),
            *sorted(run.glob("rl_model_*_steps.zip"))[-1:]]
    for k, zip_path in enumerate(zips):
        summary = evaluate.main(["--model", str(zip_path), "--n-episodes", "1", "--no-plots",
                                 "--out", str(tmp_path / f"eval{k}")])
        assert summary["n_episodes"] == 1
