"""Smoke run of the soak script (the 1,000,000-step run is manual: see softhand_env/soak.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import softhand_env

ROOT = Path(softhand_env.__file__).resolve().parent.parent


def test_soak_smoke_run_reports_consistent_figures():
    cmd = [sys.executable, "-m", "softhand_env.soak", "--steps", "2000", "--num-envs", "8",
           "--warmup", "2", "--threads", "1", "--json"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT),
                                                                      os.environ.get("PYTHONPATH")]))}
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    r = json.loads(run.stdout)
    assert r["env_steps"] == 2000 and r["num_envs"] == 8
    assert r["steps_per_second"] > 0 and r["nonfinite"] == 0
    # random actions end episodes; every end is a truncation or has exactly one reason
    assert r["episodes"] > 0
    assert r["episodes"] == r["truncations"] + sum(r["termination_reasons"].values())
    assert set(r["termination_reasons"]) <= {"nonfinite_state", "constraint_violation",
                                             "overcompressed", "grasp_lost", "contact_past_base",
                                             "success"}
    assert 0 < r["peak_rss_start_mib"] <= r["peak_rss_end_mib"]
    assert r["peak_rss_growth_percent"] < 5.0


def test_soak_format_is_readable():
    from softhand_env.soak import SoakResult, format_result

    text = format_result(SoakResult("SoftHand-v0", 2, 100, 1.0, 100.0, 3, 1,
                                    {"grasp_lost": 2}, 0, 100.0, 101.0, 1.0, 99.0, 100.0))
    assert "100 steps/s" in text and "grasp_lost: 2" in text and "+1.00 %" in text
