"""The soak script: a smoke run in the default tests, the full 1,000,000-step run as ``slow``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import softhand_env

ROOT = Path(softhand_env.__file__).resolve().parent.parent


def run_soak(*args: str, timeout: float = 300) -> dict:
    """Run ``python -m softhand_env.tools.soak ... --json`` in a fresh process; its figures."""
    cmd = [sys.executable, "-m", "softhand_env.tools.soak", *args, "--json"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT),
                                                                      os.environ.get("PYTHONPATH")]))}
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


def test_soak_smoke_run_reports_consistent_figures():
    r = run_soak("--steps", "2000", "--num-envs", "8", "--warmup", "2", "--threads", "1")
    assert r["env_steps"] == 2000 and r["num_envs"] == 8
    assert r["steps_per_second"] > 0 and r["nonfinite"] == 0
    # random actions end episodes; every end is a truncation or has exactly one reason
    assert r["episodes"] > 0
    assert r["episodes"] == r["truncations"] + sum(r["termination_reasons"].values())
    assert set(r["termination_reasons"]) <= {"nonfinite_state", "constraint_violation",
                                             "overcompressed", "grasp_lost", "contact_past_base",
                                             "tension", "slip", "success"}
    assert 0 < r["peak_rss_start_mib"] <= r["peak_rss_end_mib"]
    assert r["peak_rss_growth_percent"] < 5.0


def test_soak_format_is_readable():
    from softhand_env.tools.soak import SoakResult, format_result

    text = format_result(SoakResult("SoftHand-v0", 2, 100, 1.0, 100.0, 3, 1,
                                    {"grasp_lost": 2}, 0, 100.0, 101.0, 1.0, 99.0, 100.0))
    assert "100 steps/s" in text and "grasp_lost: 2" in text and "+1.00 %" in text


@pytest.mark.slow
def test_soak_one_million_steps_keeps_memory_flat():
    """Soak: 1,000,000 env steps of random actions on 512 envs; peak RSS must grow
    by < 5 % and nothing may become non-finite (12 s on 2 idle cores)."""
    r = run_soak("--steps", "1000000", "--num-envs", "512", timeout=1800)
    assert r["env_steps"] >= 1_000_000 and r["nonfinite"] == 0
    assert r["episodes"] == r["truncations"] + sum(r["termination_reasons"].values())
    assert r["peak_rss_growth_percent"] < 5.0
