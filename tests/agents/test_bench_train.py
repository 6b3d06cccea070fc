"""agents.bench_train: both runs complete and the last line is the fps ratio."""

from __future__ import annotations

from agents import bench_train


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
