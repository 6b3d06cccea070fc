"""benchmarks/integrator_agents.py: the shipped agents on the same goals with RK4 and ROS2."""

from __future__ import annotations

import pytest

from tests.tools.conftest import benchmark_script

pytest.importorskip("stable_baselines3")


@pytest.fixture(scope="module")
def tool():
    with benchmark_script("integrator_agents") as module:
        yield module


def test_overrides_keep_the_registered_hand_and_read_back_as_numbers(tool):
    import yaml

    assert tool.registered_integrator("SoftHandPose-v0") == "rk4"
    assert tool.registered_integrator("SoftHandPoseRandom-v1") == "ros2"
    o = tool.hand_overrides("SoftHandPoseRandom-v1", "rk4")
    assert o == {"dt": 5e-5, "integrator": "rk4"}  # the Random ids' RK4 step kept
    assert yaml.safe_load(tool.flow_mapping(o)) == o  # 5e-05 alone would read as a string
    assert tool.hand_overrides("SoftHandPose-v0", "ros2") == {"integrator": "ros2"}
    with pytest.raises(ValueError, match="integrator"):
        tool.hand_overrides("SoftHandPose-v0", "euler")
    assert {"SoftHandPose-v0", "SoftHandPose-v1"} <= set(tool.shipped_ids())


def test_tiny_run_plays_both_integrators_on_the_same_goals(tool, tmp_path, capsys):
    import yaml

    out = tmp_path / "t.md"
    assert tool.main(["--models", "SoftHandPose-v1", "--n-episodes", "2", "--seed", "5000",
                      "--results", str(tmp_path / "r"), "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == 3 and lines[2].startswith("| `SoftHandPose-v1` | ROS2 | 2 |")

    def record(integrator):
        return yaml.safe_load((tmp_path / "r" / "SoftHandPose-v1" / integrator /
                               "results.yml").read_text())

    rk4, ros2 = record("rk4"), record("ros2")
    assert [e["seed"] for e in rk4["episodes"]] == [e["seed"] for e in ros2["episodes"]]
    assert ros2["benchmark"] is True  # the id's own integrator: the benchmark run
    assert rk4["benchmark"] is False and rk4["task_overrides"]["hand_overrides"] == {
        "integrator": "rk4"}
    # the two runs integrate differently, so the final poses differ (by far less than 1 mm)
    a, b = rk4["episodes"][0]["final_pose"], ros2["episodes"][0]["final_pose"]
    assert a != b
    assert "SoftHandPose-v1 rk4: " in capsys.readouterr().err


@pytest.mark.parametrize("argv, match", [
    (["--n-episodes", "0"], "--n-episodes"),
    (["--seed", "-1"], "--seed"),
    (["--models", "SoftHand-v0"], "invalid choice"),
])
def test_bad_arguments_are_one_line_errors(tool, argv, match):
    from softhand_env.cli import CliError

    with pytest.raises(CliError, match=match):
        tool.main(argv)


@pytest.mark.slow
def test_shipped_agents_succeed_within_two_points_with_either_integrator(tool, tmp_path):
    """Every shipped default model on its id's first 100 test goals: the success rates with
    RK4 and ROS2 differ by at most 2 points (measured: at most 1, docs/integrator.md)."""
    for env_id in tool.shipped_ids():
        rates = {}
        for integrator in tool.INTEGRATORS:
            played = tool.play(env_id, integrator, 100, 10000, tmp_path / env_id / integrator)
            rates[integrator] = sum(played.success)
        assert abs(rates["rk4"] - rates["ros2"]) <= 2, (env_id, rates)
