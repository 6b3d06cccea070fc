"""Smoke test of the environment benchmark (tiny sizes; no timing is asserted)."""

from __future__ import annotations

from softhand_env.tools import bench_env


def test_bench_env_runs_and_reports_every_mode(capsys):
    bench_env.main(["--sizes", "2", "--env-steps", "40", "--repeats", "1", "--async-max", "0"])
    out = capsys.readouterr().out
    for label in ("kernel", "single (gym.make)", "sync", "async", "vector_entry_point"):
        assert label in out
    assert "skipped" in out  # async above --async-max


def test_bench_env_reset_cost_mode_reports_cache_off_and_on(capsys):
    bench_env.main(["--episode-steps", "5", "--env-steps", "20", "--repeats", "1"])
    out = capsys.readouterr().out
    assert "grasp cache off" in out and "grasp cache on" in out
