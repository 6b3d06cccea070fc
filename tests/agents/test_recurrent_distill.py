"""The recurrent (GRU) student of agents.recurrent_distill: acting step by step is the fitted
sequence model, a saved student re-validates to its record, bad inputs are refused."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import torch
import yaml

from agents import recurrent_distill as rd
from agents.common.cli import UserError

TEACHER = "SoftHandPoseRandom-v1"  # the shipped fingertip student (a blind policy)
STUDENT = ["obs_mode:proprio", "history_len:1", "onset_obs:true", "setpoint_ramp_ms:80"]
TINY = ["--iterations", "2", "--n-envs", "6", "--updates", "2", "--batch-episodes", "3",
        "--eval-every", "1", "--eval-episodes", "4", "--eval-seed", "5000"]


def test_stepping_is_the_sequence_model_and_clearing_restarts_a_row():
    torch.manual_seed(0)
    net = rd.build_student(5, 16)
    x = np.random.default_rng(0).normal(size=(3, 7, 5)).astype(np.float32)
    with torch.no_grad():
        whole, _ = net(torch.as_tensor(x))
    player = rd.RecurrentPlayer(net, 3)
    steps = np.stack([player.act(x[:, t]) for t in range(7)], axis=1)
    np.testing.assert_allclose(steps, np.clip(whole.numpy(), -1, 1), rtol=0, atol=1e-6)
    # row 1 starts over: it acts as a fresh player on the same inputs, rows 0 and 2 go on
    player.clear(np.array([1]))
    fresh = rd.RecurrentPlayer(net, 3)
    a, b = player.act(x[:, 0]), fresh.act(x[:, 0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.allclose(a[0], b[0])


def test_episodes_are_padded_and_masked():
    xs = [np.ones((3, 2)), 2 * np.ones((5, 2))]
    ys = [np.ones((3, 2)), np.ones((5, 2))]
    x, y, mask = rd.episode_batch(xs, ys)
    assert x.shape == (2, 5, 2) and y.shape == (2, 5, 2) and x.dtype == np.float32
    assert mask.sum(axis=1).tolist() == [3, 5]
    assert (x[0, 3:] == 0).all() and (x[1] == 2).all()


@pytest.fixture(scope="module")
def student(tmp_path_factory):
    out = tmp_path_factory.mktemp("gru") / "student"
    record = rd.main(["--teacher", TEACHER, "--env-kwargs", *STUDENT, *TINY, "--out", str(out)])
    return out, record


def test_a_saved_student_revalidates_to_its_record(student):
    out, record = student
    saved = yaml.safe_load((out / "student.yml").read_text())
    assert saved["env_kwargs"]["obs_mode"] == "proprio" and saved["env_kwargs"]["onset_obs"]
    assert saved["env_kwargs"]["setpoint_ramp_ms"] == 80
    assert [p["iteration"] for p in saved["curve"]] == [0, 1]
    assert len(saved["teacher"]["sha256"]) == 64
    best = saved["best_validation"]
    summary = rd.main(["--play", str(out), "--eval-episodes", "4", "--eval-seed", "5000"])
    for key in ("success_rate", "success_strict", "failure_rate", "median_x_mm"):
        assert summary[key] == best[key], key
    assert record["best_validation"] == best


def test_bad_inputs_are_refused(student, tmp_path):
    out, _ = student
    with pytest.raises(UserError, match="exists"):
        rd.main(["--teacher", TEACHER, *TINY, "--out", str(out)])
    with pytest.raises(UserError, match="eval-seed"):  # validation goals below the test seeds
        rd.main(["--play", str(out), "--eval-episodes", "4", "--eval-seed", "9998"])
    with pytest.raises(UserError, match="may set only"):
        rd.main(["--teacher", TEACHER, "--env-kwargs", "max_delta_deg:3", *TINY,
                 "--out", str(tmp_path / "x")])
    with pytest.raises(UserError, match="blind policy"):
        rd.main(["--teacher", "SoftHandPoseRandom-v1_teacher", *TINY,
                 "--out", str(tmp_path / "y")])
    with pytest.raises(UserError, match="--teacher .* or --play"):
        rd.main(["--out", str(tmp_path / "z")])
    with pytest.raises(UserError, match="not found"):
        rd.main(["--play", str(tmp_path)])


class _Payload:
    def __reduce__(self):
        return (print, ("code ran",))


def test_playing_runs_no_code_from_the_files(student, tmp_path, capsys):
    out, _ = student
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "student.yml").write_text((out / "student.yml").read_text())
    (bad / "student.pt").write_bytes(pickle.dumps(_Payload()))
    with pytest.raises(UserError, match="does not fit"):
        rd.main(["--play", str(bad), "--eval-episodes", "4"])
    assert "code ran" not in capsys.readouterr().out
    (bad / "student.yml").write_text("!!python/object/apply:os.system ['echo hi']\n")
    with pytest.raises(UserError, match="not plain YAML"):
        rd.main(["--play", str(bad), "--eval-episodes", "4"])


def test_an_interrupted_run_saves_its_best_validated_student(tmp_path):
    """SIGINT during the run stops it at the next env step or minibatch; the student of the
    best validated iteration is saved and re-validates to its record."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "student"
    cmd = [sys.executable, "-W", "ignore", "-m", "agents.recurrent_distill", "--teacher",
           TEACHER, "--env-kwargs", *STUDENT, *TINY, "--iterations", "1000", "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": str(root)})
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            if line.startswith("iteration 1 "):
                break
        proc.send_signal(signal.SIGINT)
        rest, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err[-2000:]
    assert "SIGINT" in err and "Traceback" not in err, err[-2000:]
    record = yaml.safe_load((out / "student.yml").read_text())
    assert record["interrupted"] is True and len(record["curve"]) >= 2
    best = record["best_validation"]
    summary = rd.main(["--play", str(out), "--eval-episodes", "4", "--eval-seed", "5000"])
    assert summary["success_rate"] == best["success_rate"]
    assert summary["median_x_mm"] == best["median_x_mm"]
