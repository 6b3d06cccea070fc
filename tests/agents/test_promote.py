"""Promoting a run's best validation model (agents.runs.promote): the chosen model becomes the
final one with its own statistics, the previous final model is kept and still loads with its
statistics, the record says what was promoted, the checksums are resealed, and a wrong or
tampered input is refused before anything is written."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.common import cli
from agents.runs import promote as promote_mod
from agents.runs.loading import ModelPolicy, shipped_models
from agents.runs.model_files import sha256
from agents.runs.writing import read_run

ROOT = Path(__file__).resolve().parents[2]
ENV = "SoftHandTranslate-v0"


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A tiny PPO run with validation (``best_model.zip``) and checkpoints at 128 and 256
    env steps."""
    log = tmp_path_factory.mktemp("promote")
    proc = subprocess.run(
        [sys.executable, "-m", "agents.train", "--env", ENV, "--seed", "5",
         "--n-timesteps", "384", "--eval-freq", "64", "--eval-episodes", "2",
         "--save-freq", "128", "--log-folder", str(log), "--no-progress-bar",
         "--env-kwargs", "max_episode_steps:20",
         "--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return log / "ppo" / f"{ENV}_1"


@pytest.fixture
def run(trained, tmp_path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(trained, copy)
    return copy


def _obs(n: int = 8) -> np.ndarray:
    import gymnasium as gym

    env = gym.make(ENV)
    obs = [env.reset(seed=k)[0] for k in range(n)]
    env.close()
    return np.stack(obs)


def _actions(spec: Path) -> np.ndarray:
    policy = ModelPolicy(spec)
    return np.stack([policy.predict(o, deterministic=True)[0] for o in _obs()])


def test_the_best_model_becomes_the_final_one_and_the_final_one_is_kept(run):
    best_zip, final_zip = run / "best_model.zip", run / f"{ENV}.zip"
    before = {name: sha256(run / name) for name in
              (f"{ENV}.zip", f"{ENV}/vecnormalize.npz", f"{ENV}/vecnormalize.pkl",
               "best_model.zip", "best_model_vecnormalize.npz", "best_model_vecnormalize.pkl")}
    best_actions, final_actions = _actions(best_zip), _actions(run)
    _, _, saved = read_run(run)
    assert sha256(best_zip) != sha256(final_zip)  # the tiny run's best is not its end

    promote_mod.promote(run)

    after = {name: sha256(run / name) for name in
             (f"{ENV}.zip", f"{ENV}/vecnormalize.npz", f"{ENV}/vecnormalize.pkl",
              "final_model.zip", "final_model_vecnormalize.npz",
              "final_model_vecnormalize.pkl")}
    assert after[f"{ENV}.zip"] == before["best_model.zip"]
    assert after[f"{ENV}/vecnormalize.npz"] == before["best_model_vecnormalize.npz"]
    assert after[f"{ENV}/vecnormalize.pkl"] == before["best_model_vecnormalize.pkl"]
    assert after["final_model.zip"] == before[f"{ENV}.zip"]
    assert after["final_model_vecnormalize.npz"] == before[f"{ENV}/vecnormalize.npz"]
    _, _, record = read_run(run)
    assert record["shipped_model"] == {"from": "best_model.zip",
                                       "timesteps": saved["best_validation"]["timesteps"]}
    assert record["weights_sha256"][f"{ENV}.zip"] == record["weights_sha256"]["best_model.zip"]
    assert {"final_model.zip", "final_model_vecnormalize.npz"} <= set(record["sha256"])
    # the run (checksums and manifest verified on loading) now plays the best model, and the
    # kept final model plays as before, with its own statistics
    np.testing.assert_array_equal(_actions(run), best_actions)
    np.testing.assert_array_equal(_actions(run / "final_model.zip"), final_actions)
    assert not list(run.rglob("*.tmp"))


def test_a_checkpoint_can_be_promoted_with_its_step_count(run):
    promote_mod.promote(run, "rl_model_128_steps.zip")
    assert sha256(run / f"{ENV}.zip") == sha256(run / "rl_model_128_steps.zip")
    assert (sha256(run / f"{ENV}/vecnormalize.npz")
            == sha256(run / "rl_model_vecnormalize_128_steps.npz"))
    _, _, record = read_run(run)
    assert record["shipped_model"] == {"from": "rl_model_128_steps.zip", "timesteps": 128}
    ModelPolicy(run)  # loads: the seal is valid


def _refused(capsys, argv, fragment):
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(promote_mod.main, argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err


def _files(run: Path) -> dict[str, str]:
    return {p.relative_to(run).as_posix(): sha256(p) for p in run.rglob("*") if p.is_file()}


def test_a_missing_run_directory_is_one_line(tmp_path, capsys):
    _refused(capsys, [str(tmp_path / "nowhere")], "no such run directory")


def test_a_shipped_model_is_never_written_to(capsys):
    shipped = shipped_models()["SoftHandReorientRandom-v1"].parent
    files = _files(shipped)
    _refused(capsys, [str(shipped)], "inside the package's model folder")
    assert _files(shipped) == files


def test_a_second_promotion_is_refused(run, capsys):
    cli.run_cli(promote_mod.main, [str(run)])
    capsys.readouterr()
    files = _files(run)
    _refused(capsys, [str(run)], "already promoted")
    assert _files(run) == files


@pytest.mark.parametrize("source, fragment", [
    ("../best_model.zip", "--source must be"),
    ("model.zip", "--source must be"),
    ("best_model.pkl", "--source must be"),
    ("rl_model_999_steps.zip", "no such model"),
])
def test_a_wrong_source_is_refused_before_anything_is_written(run, capsys, source, fragment):
    files = _files(run)
    _refused(capsys, [str(run), "--source", source], fragment)
    assert _files(run) == files


def test_a_tampered_model_or_statistics_is_refused_before_anything_is_written(run, capsys):
    stats = run / "best_model_vecnormalize.npz"
    stats.write_bytes(stats.read_bytes() + b"\0")
    files = _files(run)
    _refused(capsys, [str(run)], "does not match the checksum")
    assert _files(run) == files


def test_missing_statistics_of_the_promoted_model_are_refused(run, capsys):
    (run / "best_model_vecnormalize.npz").unlink()
    files = _files(run)
    _refused(capsys, [str(run)], "must both exist")
    assert _files(run) == files
