"""A model directory cannot redefine the task: the registered id's task keywords are the
evaluation's, a config that differs is refused (one line, exit 2) unless the user overrides the
keys on the command line (then the results say ``benchmark: false``), the wrappers are an
allow-list of classes with checked keywords, and an edited config.yml is detected."""

from __future__ import annotations

import shutil
import sys
import time

import pytest
import yaml

from agents import evaluate
from agents.common import cli
from agents.runs import loading
from agents.runs.layout import MANIFEST_FILE
from agents.runs.task_keywords import (
    AGENT_KEYS,
    REWARD_KEYS,
    VIEWER_KEYS,
    benchmark_steps,
    task_keys,
)
from agents.runs.writing import reseal
from agents.runs.zoo_dialect import zoo_yaml_dump, zoo_yaml_load
from softhand_env.envs.options import KEYWORDS

SHIPPED = loading.shipped_models()
ENV = "SoftHandTranslate-v0"
#: Seconds a refusal may take (it comes before any episode; most of it is torch's import).
FAST_S = 60.0


def _copy(tmp_path, env_id=ENV):
    run = tmp_path / "run"
    shutil.copytree(SHIPPED[env_id].parent, run)
    return run


def _edit(run, edit, env_id=ENV, seal=True):
    """Apply ``edit(config)`` to the run's config.yml; ``seal``: re-seal it (as an author who
    regenerates the manifest), so the check under test is not the manifest's."""
    path = run / env_id / "config.yml"
    config = zoo_yaml_load(path.read_text())
    edit(config)
    zoo_yaml_dump(config, path)
    if seal:
        reseal(run)


def _refused(capsys, argv, fragment, main=evaluate.main, limit=FAST_S):
    start = time.monotonic()
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(main, argv)
    elapsed = time.monotonic() - start
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err
    assert elapsed < limit, elapsed
    return err


def _eval_argv(run, *extra):
    return ["--model", str(run), "--n-episodes", "1", "--no-plots", *extra]


def test_every_keyword_is_the_agents_the_tasks_the_rewards_or_the_viewers():
    classes = [set(AGENT_KEYS), set(REWARD_KEYS), set(VIEWER_KEYS), set(task_keys())]
    every = set(KEYWORDS) | {"goal_obs", "privileged_obs", "max_episode_steps"}
    assert set().union(*classes) == every
    assert sum(len(c) for c in classes) == len(every)  # disjoint
    assert {"goal_x_range_mm", "x_tolerance_mm", "max_episode_steps", "hand",
            "hand_overrides", "randomize", "obs_noise", "setpoint_latency"} <= set(task_keys())


def test_episode_length_is_the_ids_duration_at_the_models_control_period():
    assert benchmark_steps("SoftHandPose-v0", 0.02) == 400
    assert benchmark_steps("SoftHandPose-v0", 0.16) == 50  # 8 s, the shipped Pose model's
    assert benchmark_steps("SoftHandTranslate-v0", 0.16) == 31  # floor(5 s / 0.16 s)


@pytest.mark.parametrize("key, value", [("goal_x_range_mm", 0.001), ("max_episode_steps", -1),
                                        ("max_episode_steps", 10**15),
                                        ("hand_overrides", {"Kd": 1e6}),
                                        ("x_tolerance_mm", 50.0)])
def test_a_config_that_redefines_the_task_is_refused(tmp_path, capsys, key, value):
    run = _copy(tmp_path)
    _edit(run, lambda c: c["env_kwargs"].update({key: value}))
    err = _refused(capsys, _eval_argv(run, "--out", str(tmp_path / "o")), key)
    assert "registered id" in err or "max_episode_steps must be" in err
    assert not (tmp_path / "o").exists()


def test_a_task_override_on_the_command_line_is_labelled_not_the_benchmark(tmp_path, capsys):
    run, out = _copy(tmp_path), tmp_path / "o"
    _edit(run, lambda c: c["env_kwargs"].update({"goal_x_range_mm": 0.001}))
    summary = evaluate.main(_eval_argv(run, "--out", str(out), "--task-kwargs",
                                       "goal_x_range_mm:0.001"))
    printed = capsys.readouterr().out
    assert "NOT the benchmark" in printed and "goal_x_range_mm=0.001" in printed
    results = yaml.safe_load((out / "results.yml").read_text())
    assert results["benchmark"] is False
    assert results["task_overrides"] == {"goal_x_range_mm": 0.001}
    assert summary["n_episodes"] == 1
    # a shipped model evaluated plainly is the benchmark
    evaluate.main(["--model", ENV, "--n-episodes", "1", "--no-plots", "--out",
                   str(tmp_path / "b")])
    assert yaml.safe_load((tmp_path / "b" / "results.yml").read_text())["benchmark"] is True
    # only task keywords may be overridden
    _refused(capsys, _eval_argv(ENV, "--out", str(tmp_path / "c"), "--task-kwargs",
                                "control_dt:0.1"), "not task keywords")


def test_an_edited_config_is_detected_by_the_manifest(tmp_path, capsys):
    run = _copy(tmp_path)
    _edit(run, lambda c: c.update({"learning_rate": 0.5}), seal=False)
    _refused(capsys, _eval_argv(run), "the run config was edited")
    (run / ENV / MANIFEST_FILE).unlink()
    _refused(capsys, _eval_argv(run), f"{MANIFEST_FILE} is missing")


def test_render_keywords_and_file_writing_wrappers_are_refused(tmp_path, capsys):
    run = _copy(tmp_path)
    videos = tmp_path / "videos"
    _edit(run, lambda c: c.update(
        {"env_wrapper": [{"gymnasium.wrappers.RecordVideo": {"video_folder": str(videos)}}]}))
    _refused(capsys, _eval_argv(run), "refused")
    _edit(run, lambda c: (c.pop("env_wrapper"), c["env_kwargs"].update(
        {"render_mode": "rgb_array"})))
    _refused(capsys, _eval_argv(run), "render_mode")
    assert not videos.exists()


def test_a_wrapper_path_is_refused_before_its_module_is_imported(tmp_path, capsys):
    run = _copy(tmp_path)
    _edit(run, lambda c: c.update({"env_wrapper": "softhand_env.figures.__main__.X"}))
    sys.modules.pop("softhand_env.figures.__main__", None)
    _refused(capsys, _eval_argv(run), "refused")
    assert "softhand_env.figures.__main__" not in sys.modules


@pytest.mark.parametrize("wrapper, fragment", [
    ({"gymnasium.wrappers.FrameStackObservation": {"stack_size": 10**9}}, "stack_size"),
    ({"agents.action_history.ActionHistory": {"n": 0}}, "n must be an int"),
    ({"agents.action_history.ActionHistory": {"n": 2, "extra": 1}}, "'extra' is not allowed"),
    # an allowed wrapper whose constructor raises ValueError (Translate acts in delta mode)
    ({"agents.residual.ResidualWrapper": {"delta_deg": 0.25}}, "ResidualWrapper needs"),
])
def test_allowed_wrappers_get_checked_keywords(tmp_path, capsys, wrapper, fragment):
    run = _copy(tmp_path)
    _edit(run, lambda c: c.update({"env_wrapper": [wrapper]}))
    _refused(capsys, _eval_argv(run), fragment)


def test_a_bad_wrapper_is_one_line_through_every_loading_command(tmp_path, capsys):
    from agents import distill, pose_figures, train

    run = _copy(tmp_path)
    _edit(run, lambda c: c.update(
        {"env_wrapper": [{"agents.action_history.ActionHistory": {"n": 0}}]}))
    _refused(capsys, ["--model", str(run), "--out", str(tmp_path / "pf")],
             "n must be an int", main=pose_figures.main)
    _refused(capsys, ["--env", ENV, "--teacher", str(run), "--log-folder",
                      str(tmp_path / "d")], "n must be an int", main=distill.main)
    _refused(capsys, ["--env", ENV, "--trained-agent", str(run), "--log-folder",
                      str(tmp_path / "t"), "--n-timesteps", "1000"], "n must be an int",
             main=train.main, limit=300.0)


def test_a_directory_of_another_gymnasium_id_is_refused_before_building_it(tmp_path, capsys):
    run = _copy(tmp_path)
    (run / ENV).rename(run / "CarRacing-v3")
    (run / f"{ENV}.zip").rename(run / "CarRacing-v3.zip")
    _refused(capsys, _eval_argv(run), "not a soft-hand environment")
