"""Acceptance figures for the shipped agents on the 100 test goals (``slow``).

Each shipped model is evaluated on the 100 held-out test goals (``reset(seed=10000 + k)``)
with the benchmark's success definition (|x err| < 1 mm and/or |theta err| < 1 deg at the end
of the episode, slip termination on), next to its scripted baselines on the same goals.

* Nominal tier: Reorient and Translate >= 95 % and better than the model-based baseline (by
  success rate where the baseline fails goals, otherwise by the median final error, since
  that baseline already reaches 100 % there); Pose (learned without any plan) >= 90 %; the
  residual Pose agent (on the loop plan) >= 80 %; both Pose agents above both baselines.
* Random tier: ReorientRandom >= 95 % and above the model-based baseline; PoseRandom >= 85 %
  and at least 10 points above both the model-based baseline and the loop plan.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from agents import evaluate

COMMON = ["--n-episodes", "100", "--seed", "10000", "--no-plots"]

#: shipped model name -> (env id, lowest success rate, error keys, baselines it must beat,
#: margin in success rate over each baseline)
TARGETS = {
    "SoftHandReorient-v0": ("SoftHandReorient-v0", 0.95, ["median_theta_deg"],
                            ["model-based"], 0.0),
    "SoftHandTranslate-v0": ("SoftHandTranslate-v0", 0.95, ["median_x_mm"],
                             ["model-based"], 0.0),
    "SoftHandPose-v0": ("SoftHandPose-v0", 0.90, ["median_x_mm", "median_theta_deg"],
                        ["model-based", "loop-plan"], 0.0),
    "SoftHandPose-v0_residual": ("SoftHandPose-v0", 0.80, ["median_x_mm", "median_theta_deg"],
                                 ["model-based", "loop-plan"], 0.0),
    "SoftHandReorientRandom-v0": ("SoftHandReorientRandom-v0", 0.95, ["median_theta_deg"],
                                  ["model-based"], 0.0),
    "SoftHandPoseRandom-v0": ("SoftHandPoseRandom-v0", 0.85,
                              ["median_x_mm", "median_theta_deg"],
                              ["model-based", "loop-plan"], 0.10),
}


@functools.cache
def _baseline(policy: str, env_id: str, out: str) -> tuple[tuple[str, float], ...]:
    summary = evaluate.main(["--policy", policy, "--env", env_id, *COMMON, "--out", out])
    return tuple(summary.items())


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TARGETS))
def test_shipped_agent_meets_its_target_and_beats_its_baselines(name, tmp_path_factory):
    env_id, floor, keys, baselines, margin = TARGETS[name]
    learned = evaluate.main(["--model", name, *COMMON,  # the shipped model of that name
                             "--out", str(tmp_path_factory.mktemp("learned"))])
    for policy in baselines:
        out = Path(tmp_path_factory.getbasetemp()) / f"baseline_{policy}_{env_id}"
        baseline = dict(_baseline(policy, env_id, str(out)))
        if baseline["success_rate"] < 1.0:
            assert learned["success_rate"] >= baseline["success_rate"] + margin, (policy,
                                                                                  baseline)
            assert learned["success_rate"] > baseline["success_rate"], (policy, baseline)
        else:
            assert learned["success_rate"] == 1.0
            for key in keys:
                assert learned[key] < baseline[key], (policy, key)
    assert learned["success_rate"] >= floor, learned

