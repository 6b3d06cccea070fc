"""agents.bench_train: the runs complete and the last line is the fps ratio; the RLlib row."""

from __future__ import annotations

import sys

import pytest

from agents import bench_train
from agents.common.cli import run_cli


def test_bench_train_prints_table_and_ratio(capsys):
    ratio = bench_train.main([
        "--steps", "256", "--native-n-envs", "8", "--native-n-steps", "32",
        "--native-batch-size", "128", "--native-n-epochs", "1",
    ])
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-1] == f"native/dummy fps ratio: {ratio:.2f}" and ratio > 0
    rows = [line for line in out if line.startswith("| dummy") or line.startswith("| native")]
    assert len(rows) == 2
    assert rows[0].split("|")[2].strip() == "16"  # ppo.yml's n_envs for the dummy run
    assert rows[1].split("|")[2].strip() == "8"


def test_bench_train_rllib_row(capsys):
    pytest.importorskip("ray.rllib.algorithms.ppo", reason="needs softhand-env[rllib]")
    bench_train.main([
        "--steps", "256", "--native-n-envs", "8", "--native-n-steps", "32",
        "--native-batch-size", "128", "--native-n-epochs", "1", "--rllib",
        "--rllib-env-runners", "1", "--rllib-envs-per-runner", "2",
    ])
    out = capsys.readouterr().out.strip().splitlines()
    row = [line for line in out if line.startswith("| rllib")]
    assert len(row) == 1
    cells = [c.strip() for c in row[0].split("|")[1:-1]]
    assert cells[1] == "2" and cells[2] == "2048"  # 2 envs, 16 x 256 steps per iteration
    assert int(cells[6]) >= 256 and float(cells[8].replace(",", "")) > 0
    assert out[-2].startswith("rllib/dummy fps ratio: ")


def test_bench_train_rllib_without_rllib_is_one_line(monkeypatch, capsys):
    for name in [m for m in sys.modules if m == "ray" or m.startswith("ray.")] + ["ray"]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(SystemExit) as exc:
        run_cli(bench_train.main, ["--rllib"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: --rllib needs Ray RLlib"), err
