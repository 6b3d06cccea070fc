"""Pose comparison figures (agents.pose_figures): grid results, outputs, CLI errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents import pose_figures
from agents.common.cli import UserError, run_cli
from agents.plots.pose import OUTCOMES, signed_area

#: A 3 x 3 grid with the loop plan, goals at -12, 0, 12 mm / deg: the centre succeeds, the
#: corners outside the task box mostly do not.
SMALL = ["--policy", "loop-plan", "--grid", "3", "--span-mm", "12", "--span-deg", "12"]


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("pose_figures")
    result = pose_figures.main([*SMALL, "--out", str(out)])
    return out, result


def test_both_figures_and_the_grid_results_are_written(small_run):
    out, result = small_run
    for name in pose_figures.OUTPUTS:
        assert (out / name).stat().st_size > 1000, name
    assert result["labels"] == ["loop-plan"]
    assert result["outcome"].shape == (1, 3, 3)


def test_npz_is_consistent_with_the_success_tolerance(small_run):
    out, _ = small_run
    with np.load(out / "reachable.npz", allow_pickle=False) as z:
        d = {k: z[k] for k in z.files}
    assert list(d["labels"]) == ["loop-plan"]
    np.testing.assert_allclose(d["goal_x_mm"], [-12, 0, 12])
    np.testing.assert_allclose(d["goal_theta_deg"], [-12, 0, 12])
    assert d["outcome"].shape == d["success"].shape == d["length"].shape == (1, 3, 3)
    assert d["final_pose"].shape == (1, 3, 3, 3)
    assert d["goal"].shape == (3, 3, 2)
    np.testing.assert_allclose(d["goal"][2, 0], [-12e-3, math.radians(12)])  # [i_theta, i_x]
    assert d["seed"].ravel().tolist() == list(range(20000, 20009))
    assert set(d["outcome"].ravel()) <= set(OUTCOMES)
    assert np.array_equal(d["success"], d["outcome"] == "success")
    assert d["control_dt"].tolist() == [0.02]
    # success recomputed from the stored final poses, for the episodes that did not fail
    tol_mm, tol_deg = d["tolerance"]
    err_x = np.abs(d["final_pose"][..., 0] - d["goal"][..., 0])
    err_th = np.abs(d["final_pose"][..., 2] - d["goal"][..., 1])
    within = (err_x <= tol_mm * 1e-3) & (err_th <= math.radians(tol_deg))
    ran_out = np.isin(d["outcome"], ("success", "time"))
    assert np.array_equal(d["success"][ran_out], within[ran_out])
    assert not d["success"][~ran_out].any()
    assert (d["length"][ran_out] == 400).all()  # the time limit: 8 s at 20 ms
    assert d["success"][0, 1, 1] and not d["success"].all()  # the centre goal; not all
    np.testing.assert_allclose(d["task_box"], [10, 10])


@pytest.mark.parametrize("argv, message", [
    (["--grid", "1"], "--grid must be in [2, 101]"),
    (["--grid", "x"], "invalid int value"),
    (["--span-mm", "0"], "--span-mm must be in"),
    (["--span-deg", "nan"], "--span-deg must be in"),
    (["--goal-x-mm", "13"], "--goal-x-mm must be in [-12.0, 12.0]"),
    (["--goal-seed", "-1"], "--goal-seed must be in"),
    (["--policy", "paper"], "invalid choice"),
])
def test_bad_options_are_one_line_errors_with_exit_code_2(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        run_cli(pose_figures.main, [*SMALL, "--out", str(tmp_path / "o"), *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "o").exists()


def test_no_policy_and_a_model_for_another_task_are_refused(tmp_path):
    with pytest.raises(UserError, match="at least one --model or --policy"):
        pose_figures.main(["--out", str(tmp_path)])
    with pytest.raises(UserError, match="SoftHandTranslate-v0, not SoftHandPose-v0"):
        pose_figures.main(["--model", "SoftHandTranslate-v0", "--out", str(tmp_path)])


def test_existing_output_is_refused_without_force(small_run, tmp_path):
    out, _ = small_run
    with pytest.raises(UserError, match="already holds reachable.png.*--force"):
        pose_figures.main([*SMALL, "--out", str(out)])
    file = tmp_path / "file"
    file.write_text("")
    with pytest.raises(UserError, match="not a directory"):
        pose_figures.main([*SMALL, "--out", str(file)])


def test_policies_keep_their_command_line_order():
    args = pose_figures.parse_args(["--policy", "loop-plan", "--model", "M", "--policy",
                                    "model-based", "--out", "o"])
    assert args.policies == [("policy", "loop-plan"), ("model", "M"), ("policy", "model-based")]


def test_signed_area_of_a_loop_and_of_a_back_and_forth():
    square = np.array([[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]], dtype=float)
    assert signed_area(square[:, 0], square[:, 1]) == pytest.approx(2.0)
    assert signed_area(square[::-1, 0], square[::-1, 1]) == pytest.approx(-2.0)
    line = np.array([0.0, 3.0, 0.0, 3.0])
    assert signed_area(line, 0.5 * line) == pytest.approx(0.0)


def test_env_picks_the_pose_id_and_a_model_of_another_id_is_refused(tmp_path):
    out = tmp_path / "v1"
    result = pose_figures.main(["--env", "SoftHandPose-v1", "--model", "SoftHandPose-v1",
                                "--grid", "2", "--out", str(out)])
    assert result["outcome"].shape == (1, 2, 2)
    with np.load(out / "reachable.npz") as z:
        assert list(z["labels"]) == ["ppo SoftHandPose-v1_1"]
    with pytest.raises(UserError, match="trained on SoftHandPose-v0, not SoftHandPose-v1"):
        pose_figures.main(["--env", "SoftHandPose-v1", "--model", "SoftHandPose-v0",
                           "--out", str(tmp_path / "v0")])
