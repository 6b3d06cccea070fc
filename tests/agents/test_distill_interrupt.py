"""An interrupted distillation leaves a usable run: SIGINT or SIGTERM during a rollout (mostly
inside the numba kernel of 256 hands), during the fit or after some iterations stops
``agents.distill`` at the next env step or minibatch; the saved student (the best validated
iteration, or the current weights if none was validated) is evaluable and ``config.yml`` is
finalised (``interrupted: true``, sha256 of every model file)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from agents import evaluate
from agents.learning_curves import read_curve
from agents.runs.loading import resolve_model
from agents.runs.model_files import sha256
from tests.agents.test_distill import ENV_ID, _student_args, teacher  # noqa: F401  (fixture)

ROOT = Path(__file__).resolve().parents[2]


def _distill_and_signal(args: list[str], signum: int, wait_for: str, delay_s: float
                        ) -> tuple[Path, str]:
    """Start a long distillation, send ``signum`` ``delay_s`` after the first stdout line
    starting with ``wait_for``; returns the run directory and stdout once the process has
    ended (exit code 0, the signal named on stderr, no traceback asserted)."""
    cmd = [sys.executable, "-W", "ignore", "-m", "agents.distill", *args]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.stdout is not None
    seen = []
    try:
        run_dir = None
        for line in proc.stdout:
            seen.append(line)
            if line.startswith("run directory:"):
                run_dir = Path(line.split(":", 1)[1].strip())
            if line.startswith(wait_for):
                break
        else:
            pytest.fail(f"no {wait_for!r}: {proc.stderr.read() if proc.stderr else ''}")
        time.sleep(delay_s)
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err[-2000:]
    assert signal.Signals(signum).name in err and "Traceback" not in err, err[-2000:]
    assert run_dir is not None
    return run_dir, "".join(seen) + out


def _check_usable(run: Path, tmp_path: Path) -> dict:
    """The run's record (checksums verified on load and against the files), after playing
    its saved student on one goal with agents.evaluate."""
    record = resolve_model(run).record
    assert record["interrupted"] is True and record["trainer"] == "dagger"
    for name, digest in record["sha256"].items():  # every recorded file as it is on disk
        assert sha256(run / name) == digest, name
    assert f"{ENV_ID}.zip" in record["sha256"]
    # the test's short episodes, on purpose (labelled not the benchmark); a validation goal
    summary = evaluate.main(["--model", str(run), "--n-episodes", "1", "--seed", "5000",
                             "--task-kwargs", "max_episode_steps:8", "--no-plots",
                             "--out", str(tmp_path / "eval")])
    assert summary["n_episodes"] == 1
    return record


def test_signal_during_the_first_rollout_saves_the_current_student(tmp_path, teacher):  # noqa: F811
    """256 hands and a rollout far longer than the test: the signal lands in the first
    rollout, mostly inside the kernel; no iteration was validated."""
    args = _student_args(tmp_path, teacher) + [
        "--hyperparams", "n_envs:256", "--rollout-steps", "100000", "--iterations", "2"]
    run, out = _distill_and_signal(args, signal.SIGINT, "run directory:", 1.0)
    record = _check_usable(run, tmp_path)
    assert "best_validation" not in record and "no iteration validated" in out
    assert 0 < record["total_timesteps"] < 256 * 100_000 and record["total_timesteps"] % 256 == 0
    curve = np.load(run / "dagger_curve.npz")
    assert curve["iteration"].shape == (0,)
    assert read_curve(run)[0] == "dagger"  # the learning-curve reader takes the empty curve


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["sigterm", "sigint"])
def test_signal_after_some_iterations_saves_the_best_validated_student(tmp_path, teacher,  # noqa: F811
                                                                       signum):
    """The signal lands in iteration 2 or later (rollout, fit or validation): the saved
    student is the best of the validated iterations."""
    args = _student_args(tmp_path, teacher) + ["--iterations", "10000"]
    run, out = _distill_and_signal(args, signum, "iteration 1:", 0.5)
    record = _check_usable(run, tmp_path)
    curve = np.load(run / "dagger_curve.npz")
    assert 2 <= len(curve["iteration"]) < 10_000
    best = record["best_validation"]
    assert best["success_rate"] == curve["success_rate"].max()
    assert record["total_timesteps"] >= curve["env_steps"][-1]


@pytest.mark.slow
def test_signal_during_the_fit_saves_the_current_student(tmp_path, teacher):  # noqa: F811
    """32,000 minibatches of one sample in the first iteration: the signal lands in the fit."""
    args = _student_args(tmp_path, teacher) + ["--epochs", "1000", "--batch-size", "1"]
    run, out = _distill_and_signal(args, signal.SIGTERM, "run directory:", 2.0)
    record = _check_usable(run, tmp_path)
    assert "best_validation" not in record
    assert record["total_timesteps"] == 8 * 4  # the first rollout was complete
