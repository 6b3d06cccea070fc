"""agents.bc: behaviour cloning of a Minari dataset, saved as a run agents.evaluate plays."""

from __future__ import annotations

import numpy as np
import pytest

from agents import bc, collect, evaluate
from agents.common.cli import UserError, run_cli
from agents.runs.loading import ModelPolicy

pytest.importorskip("minari")


@pytest.fixture
def datasets(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    return tmp_path / "datasets"


def test_cloned_run_is_played_by_evaluate_with_its_validation(datasets, tmp_path):
    collect.main(["--env", "SoftHandPose-v0", "--policy", "SoftHandPose-v0", "--episodes", "4",
                  "--dataset-id", "softhand/pose/expert-v0"])
    run_dir = bc.main(["--dataset", "softhand/pose/expert-v0", "--epochs", "3",
                       "--eval-every", "1", "--eval-episodes", "3", "--net-arch", "32", "32",
                       "--log-folder", str(tmp_path / "logs")])
    assert run_dir == tmp_path / "logs" / "ppo" / "SoftHandPose-v0_1"
    policy = ModelPolicy(run_dir)  # checksums, manifest, statistics, spaces
    assert policy.normalizer is not None
    record = policy.run.record
    assert record["trainer"] == "bc"
    assert record["dataset"]["id"] == "softhand/pose/expert-v0"
    assert record["dataset"]["episodes"] == 4 and record["total_timesteps"] == 4 * 50
    assert policy.run.hyperparams["env_wrapper"] == [
        {"agents.time_feature.TimeFeature": {"max_steps": 50}}]
    best = record["best_validation"]
    assert 1 <= best["epoch"] <= 3
    # the saved model is the best validated epoch: evaluate reproduces its validation
    summary = evaluate.main(["--model", str(run_dir), "--seed", "5000", "--n-episodes", "3",
                             "--no-plots", "--out", str(tmp_path / "eval")])
    for key in ("success_rate", "median_x_mm", "median_theta_deg", "mean_return"):
        assert summary[key] == pytest.approx(best[key], rel=1e-12, abs=1e-12), key
    with np.load(run_dir / "bc_curve.npz") as curve:
        np.testing.assert_array_equal(curve["epoch"], [1, 2, 3])
        assert np.all(curve["train_mse"] > 0)


def test_cloning_lowers_the_imitation_error(datasets, tmp_path):
    collect.main(["--env", "SoftHandTranslate-v0", "--policy", "model-based", "--episodes", "3",
                  "--dataset-id", "softhand/translate/scripted-v0"])
    run_dir = bc.main(["--dataset", "softhand/translate/scripted-v0", "--epochs", "20",
                       "--eval-every", "10", "--eval-episodes", "1", "--net-arch", "64", "64",
                       "--log-folder", str(tmp_path / "logs")])
    with np.load(run_dir / "bc_curve.npz") as curve:
        assert curve["train_mse"][-1] < 0.5 * curve["train_mse"][0]
    policy = ModelPolicy(run_dir)
    assert policy.env_kwargs == {"action_mode": "absolute", "normalize_action": False}


@pytest.mark.parametrize("argv, message", [
    (["--dataset", "softhand/pose/nothing-v0"], "no local dataset"),
    (["--dataset", "softhand/pose/expert-v0", "--epochs", "0"], "--epochs"),
    (["--dataset", "softhand/pose/expert-v0", "--lr", "0"], "--lr"),
    (["--dataset", "softhand/pose/expert-v0", "--net-arch", "0"], "--net-arch"),
    (["--dataset", "softhand/pose/expert-v0", "--run-name", "a/b"], "--run-name"),
])
def test_bad_input_is_one_line_and_exit_2(datasets, tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        run_cli(bc.main, [*argv, "--log-folder", str(tmp_path / "logs")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "logs" / "ppo").exists()


def test_settings_refuse_missing_dataset_flag():
    with pytest.raises(UserError, match="--dataset"):
        bc.parse_args([])
