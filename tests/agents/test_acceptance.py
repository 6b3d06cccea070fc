"""Acceptance figures for the shipped agents on the test goals (``slow``).

Each shipped model is evaluated on the held-out test goals (``reset(seed=10000 + k)``; 300 for
the Pose and PoseRandom agents, whose figures lie nearest a threshold, 100 for the others)
with the benchmark's success definition (|x err| < 1 mm and/or |theta err| < 1 deg at the end
of the episode, slip termination on), next to its scripted baselines on the same goals.

Each floor is at least the project's target for that model. The evaluation is deterministic;
measured on 300 goals (docs/results.md): Pose 299/300 (95 % CI 98.1-99.9 %) -> floor 98 %, the
lower end of that interval rounded down (above the 90 % target); PoseRandom 266/300 (84.6-91.8
%) -> floor 85 %, its target (255 of 300 needed: a margin of 11 goals). Its interval reaches
below 85 %: the target is met as a point estimate, not at 95 % confidence (docs/results.md).

* Nominal tier: Reorient and Translate >= 95 % and better than the model-based baseline (by
  success rate where the baseline fails goals, otherwise by the median final error, since
  that baseline already reaches 100 % there); Pose (learned without any plan, target 90 %)
  >= 98 % on 300 goals; the residual Pose agent (on the loop plan) >= 80 %; both Pose agents
  above both baselines.
* Random tier: ReorientRandom >= 95 % and above the model-based baseline; PoseRandom (target
  85 %) >= 85 % on 300 goals and at least 10 points above both the model-based baseline and
  the loop plan.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from agents import evaluate

COMMON = ["--seed", "10000", "--no-plots"]

#: Test goals per shipped model (100 unless named here).
N_GOALS = {"SoftHandPose-v0": 300, "SoftHandPoseRandom-v0": 300}

#: shipped model name -> (env id, lowest success rate, error keys, baselines it must beat,
#: margin in success rate over each baseline)
TARGETS = {
    "SoftHandReorient-v0": ("SoftHandReorient-v0", 0.95, ["median_theta_deg"],
                            ["model-based"], 0.0),
    "SoftHandTranslate-v0": ("SoftHandTranslate-v0", 0.95, ["median_x_mm"],
                             ["model-based"], 0.0),
    "SoftHandPose-v0": ("SoftHandPose-v0", 0.98, ["median_x_mm", "median_theta_deg"],
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
def _baseline(policy: str, env_id: str, n: int, out: str) -> tuple[tuple[str, float], ...]:
    summary = evaluate.main(["--policy", policy, "--env", env_id, "--n-episodes", str(n),
                             *COMMON, "--out", out])
    return tuple(summary.items())


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TARGETS))
def test_shipped_agent_meets_its_target_and_beats_its_baselines(name, tmp_path_factory):
    env_id, floor, keys, baselines, margin = TARGETS[name]
    n = N_GOALS.get(name, 100)
    learned = evaluate.main(["--model", name, "--n-episodes", str(n), *COMMON,  # shipped
                             "--out", str(tmp_path_factory.mktemp("learned"))])
    assert learned["n_episodes"] == n
    for policy in baselines:
        out = Path(tmp_path_factory.getbasetemp()) / f"baseline_{policy}_{env_id}_{n}"
        baseline = dict(_baseline(policy, env_id, n, str(out)))
        if baseline["success_rate"] < 1.0:
            assert learned["success_rate"] >= baseline["success_rate"] + margin, (policy,
                                                                                  baseline)
            assert learned["success_rate"] > baseline["success_rate"], (policy, baseline)
        else:
            assert learned["success_rate"] == 1.0
            for key in keys:
                assert learned[key] < baseline[key], (policy, key)
    assert learned["success_rate"] >= floor, learned

