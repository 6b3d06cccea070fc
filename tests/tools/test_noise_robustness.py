"""benchmarks/noise_robustness.py: each row played at each sensing point on the same
validation goals; table, CSV and figure."""

from __future__ import annotations

import csv

import pytest

from tests.tools.conftest import benchmark_script

pytest.importorskip("stable_baselines3")
pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def tool():
    with benchmark_script("noise_robustness") as module:
        yield module


def test_points_and_rows(tool):
    import gymnasium as gym

    import softhand_env  # noqa: F401

    assert tool.point_kwargs("ideal") == ["sensor_model:ideal", "rand_sensors:false"]
    assert tool.point_kwargs(0.5) == ["sensor_noise_scale:0.5"]
    assert tool.point_name(2.0) == "2x" and tool.point_name("ideal") == "ideal"
    for row in tool.ROWS.values():
        assert row.env_id.endswith("-v1") and row.env_id in gym.registry
        assert ("--allow-off-signature" in row.argv()) == (row.kind == "model")


def test_tiny_run_writes_table_csv_and_figure(tool, tmp_path, capsys):
    import yaml

    out, table_csv, png = tmp_path / "t.md", tmp_path / "t.csv", tmp_path / "t.png"
    assert tool.main(["--rows", "pose-random", "loop-plan", "--scales", "0", "4",
                      "--n-episodes", "2", "--results", str(tmp_path / "r"), "--out", str(out),
                      "--csv", str(table_csv), "--png", str(png)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "| policy (`--model` / `--policy`) | env | ideal | 0x | 4x |"
    assert len(lines) == 4 and all(line.count("|") == 6 for line in lines)
    assert lines[2].startswith("| PoseRandom") and "`SoftHandPoseRandom-v1`" in lines[2]
    rows = list(csv.DictReader(table_csv.open()))
    assert [(r["row"], r["point"]) for r in rows] == [
        (name, p) for name in ("pose-random", "loop-plan") for p in ("ideal", "0x", "4x")]
    for r in rows:
        k, n = int(r["successes"]), int(r["n"])
        assert n == 2 and float(r["wilson_low"]) <= k / n <= float(r["wilson_high"])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    def record(value, point):
        return yaml.safe_load((tmp_path / "r" / value / point / "results.yml").read_text())

    ideal, zero = record("SoftHandPoseRandom-v0", "ideal"), record("SoftHandPoseRandom-v0",
                                                                   "scale0")
    # validation goals, the same at every point; off-signature only where the sensing differs
    assert [e["seed"] for e in zero["episodes"]] == [5000, 5001]
    assert [e["goal"] for e in ideal["episodes"]] == [e["goal"] for e in zero["episodes"]]
    assert not any(f.startswith("sensor_model") for f in ideal["off_signature"])
    assert any(f.startswith("sensor_model") for f in zero["off_signature"])
    assert "pose-random 4x: " in capsys.readouterr().err


@pytest.mark.parametrize("argv, match", [
    (["--seed", "10000"], "test seeds"),
    (["--seed", "9990", "--n-episodes", "20"], "test seeds"),
    (["--scales", "-1"], r"--scales must be numbers in \[0, 10\]"),
    (["--n-episodes", "0"], "--n-episodes"),
])
def test_bad_arguments_are_one_line_errors(tool, argv, match):
    from softhand_env.cli import CliError

    with pytest.raises(CliError, match=match):
        tool.main(argv)
