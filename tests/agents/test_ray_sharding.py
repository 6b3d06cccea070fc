"""Episodes split over Ray workers (agents.play.sharding): equal to the serial run, errors."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import yaml

from agents import evaluate, pose_figures
from agents.common.cli import run_cli
from agents.play import sharding

#: Validation goals, shortened episodes (the task keyword on purpose), no plots.
EVAL = ["--n-episodes", "5", "--seed", "5000", "--no-plots",
        "--task-kwargs", "max_episode_steps:40"]


def _square(chunk):
    return [x * x for x in chunk]


def test_split_and_merge_keep_the_order():
    items = list(range(11))
    for n in (1, 2, 3, 11, 20):
        chunks = sharding.split(items, n)
        assert len(chunks) == min(n, 11)
        assert max(map(len, chunks)) - min(map(len, chunks)) <= 1
        assert sharding.merge(chunks) == items
    assert sharding.map_chunks(_square, [[1, 2], [3]]) == [[1, 4], [9]]  # serial, no Ray


def test_ray_workers_without_ray_is_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        run_cli(evaluate.main, ["--policy", "model-based", "--env", "SoftHandTranslate-v0",
                                "--ray-workers", "2", *EVAL])
    assert exc.value.code == 2
    assert capsys.readouterr().err.strip() == "error: --ray-workers needs --ray"


@pytest.mark.parametrize("main, argv", [
    (evaluate.main, ["--policy", "model-based", "--env", "SoftHandTranslate-v0", *EVAL]),
    (pose_figures.main, ["--policy", "loop-plan", "--grid", "2", "--out", "unused"]),
])
def test_missing_ray_is_one_line_and_exit_2(monkeypatch, capsys, tmp_path, main, argv):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        run_cli(main, [*argv, "--ray"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: --ray needs Ray"), err
    assert sharding.INSTALL_HINT in err[0]
    assert not any(tmp_path.iterdir())  # refused before any work


def test_map_chunks_on_ray_keeps_the_chunk_order(local_ray):
    chunks = sharding.split(list(range(7)), 3)
    assert sharding.map_chunks(_square, chunks, sharding.LOCAL, 2) == [
        _square(c) for c in chunks]


@pytest.mark.parametrize("choice", [
    ["--policy", "model-based", "--env", "SoftHandTranslate-v0"],
    ["--model", "SoftHandReorient-v0"],
])
def test_evaluate_on_two_ray_workers_equals_the_serial_run(local_ray, tmp_path, choice):
    serial = evaluate.main([*choice, *EVAL, "--out", str(tmp_path / "serial")])
    sharded = evaluate.main([*choice, *EVAL, "--out", str(tmp_path / "ray"), "--ray",
                             "--ray-workers", "2"])
    assert sharded == serial
    a = yaml.safe_load((tmp_path / "serial" / "results.yml").read_text())
    b = yaml.safe_load((tmp_path / "ray" / "results.yml").read_text())
    assert a["episodes"] == b["episodes"]  # every record, in goal order
    assert [ep["seed"] for ep in b["episodes"]] == list(range(5000, 5005))


def test_pose_grid_on_two_ray_workers_equals_the_serial_run(local_ray, tmp_path):
    argv = ["--policy", "loop-plan", "--grid", "3", "--goal-seed", "5000"]
    serial = pose_figures.main([*argv, "--out", str(tmp_path / "serial")])
    sharded = pose_figures.main([*argv, "--out", str(tmp_path / "ray"), "--ray",
                                 "--ray-workers", "2"])
    np.testing.assert_array_equal(sharded["outcome"], serial["outcome"])
    with np.load(tmp_path / "serial" / "reachable.npz") as za, \
            np.load(tmp_path / "ray" / "reachable.npz") as zb:
        for key in ("success", "final_pose", "length", "outcome", "seed"):
            np.testing.assert_array_equal(za[key], zb[key], err_msg=key)
