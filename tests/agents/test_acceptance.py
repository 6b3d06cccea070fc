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
* ``-v1`` (300 goals each): the benchmark-v1 targets (Pose 97 %, ReorientRandom 98 %,
  PoseRandom 95 % with the interval's lower end at 92 %, strict success Pose 90 % and
  PoseRandom 80 %, no physical failure); those measured below target are strict xfails
  that name the figure reached.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import pytest

from agents import evaluate
from agents.common.metrics import wilson_interval

COMMON = ["--seed", "10000", "--no-plots"]

#: Test goals per shipped model (100 unless named here).
N_GOALS = {"SoftHandPose-v0": 300, "SoftHandPoseRandom-v0": 300,
           **{f"SoftHand{task}-v1": 300 for task in ("Translate", "Reorient", "Pose",
                                                    "ReorientRandom", "PoseRandom")},
           "SoftHandTranslate-v1_finetuned": 300, "SoftHandPose-v1_proprio": 300,
           "SoftHandPoseRandom-v1_proprio_ramp": 300}

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
    # the -v1 models (realistic sensors, physical checks, fast integrator), floors at the
    # targets of benchmark v1; measured on 300 goals: Translate 300/300, Reorient 300/300,
    # Pose 300/300 (strict 278/300; joint-only Pose 292/300), ReorientRandom 296/300,
    # PoseRandom 295/300 (strict 241/300, no physical failure), PoseRandom without
    # fingertips (the grasp onset and an 80 ms set-point ramp) 288/300 and no physical
    # failure (docs/results.md)
    # Translate-v1's default model (trained from scratch) reaches 100 % like the model-based
    # baseline but not its median final error (0.177 against 0.117 mm on these goals), so it
    # is held to the floor only; the model fine-tuned from -v0 beats the baseline (0.074 mm)
    "SoftHandTranslate-v1": ("SoftHandTranslate-v1", 0.95, ["median_x_mm"], [], 0.0),
    "SoftHandTranslate-v1_finetuned": ("SoftHandTranslate-v1", 0.95, ["median_x_mm"],
                                       ["model-based"], 0.0),
    "SoftHandReorient-v1": ("SoftHandReorient-v1", 0.95, ["median_theta_deg"],
                            ["model-based"], 0.0),
    "SoftHandPose-v1": ("SoftHandPose-v1", 0.97, ["median_x_mm", "median_theta_deg"],
                        ["model-based", "loop-plan"], 0.0),
    # the earlier Pose-v1 student, joints and torques only (97.3 % on these goals)
    "SoftHandPose-v1_proprio": ("SoftHandPose-v1", 0.97, ["median_x_mm", "median_theta_deg"],
                                ["model-based", "loop-plan"], 0.0),
    "SoftHandReorientRandom-v1": ("SoftHandReorientRandom-v1", 0.98, ["median_theta_deg"],
                                  ["model-based"], 0.0),
    "SoftHandPoseRandom-v1": ("SoftHandPoseRandom-v1", 0.95,
                              ["median_x_mm", "median_theta_deg"],
                              ["model-based", "loop-plan"], 0.0),
    # the student without fingertip sensing (joints, torques and the joint angles where the
    # grasp began, onset_obs) with an 80 ms set-point ramp (setpoint_ramp_ms): target 85 %,
    # 288/300 measured
    "SoftHandPoseRandom-v1_proprio_ramp": ("SoftHandPoseRandom-v1", 0.85,
                                           ["median_x_mm", "median_theta_deg"],
                                           ["model-based", "loop-plan"], 0.0),
}

#: Further targets of the -v1 models on the same 300 goals: (lowest lower end of the Wilson
#: 95 % interval of success, lowest strict success (0.5 mm / 0.5 deg), or None where none is
#: set). Every -v1 model must also end no episode in a physical failure.
TARGETS_V1 = {
    "SoftHandTranslate-v1": (None, None),
    "SoftHandReorient-v1": (None, None),
    "SoftHandPose-v1": (None, 0.90),
    "SoftHandPose-v1_proprio": (None, None),
    "SoftHandReorientRandom-v1": (None, None),
    "SoftHandPoseRandom-v1": (0.92, 0.80),
    "SoftHandPoseRandom-v1_proprio_ramp": (None, None),
}

#: (model, criterion) pairs measured below their target (docs/results.md): they fail until a
#: model meets the target (strict xfail, so a model that meets it turns them into errors to
#: be recorded here).
UNMET_V1: dict[tuple[str, str], str] = {}


@functools.cache
def _summary(base: str, *argv: str) -> tuple[tuple[str, object], ...]:
    """``agents.evaluate`` on the test goals (``argv`` plus :data:`COMMON`), once per
    ``argv`` in the session (its results under ``base``, a directory named by ``argv``)."""
    out = Path(base) / "_".join(a.lstrip("-") for a in argv)
    return tuple(evaluate.main([*argv, *COMMON, "--out", str(out)]).items())


def _learned(name: str, base: Path) -> dict[str, object]:
    """The shipped model ``name`` on its :data:`N_GOALS` test goals."""
    return dict(_summary(str(base), "--model", name, "--n-episodes",
                         str(N_GOALS.get(name, 100))))


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TARGETS))
def test_shipped_agent_meets_its_target_and_beats_its_baselines(name, tmp_path_factory):
    env_id, floor, keys, baselines, margin = TARGETS[name]
    n = N_GOALS.get(name, 100)
    base = Path(tmp_path_factory.getbasetemp())
    learned: dict[str, Any] = _learned(name, base)
    assert learned["n_episodes"] == n
    for policy in baselines:
        baseline: dict[str, Any] = dict(_summary(str(base), "--policy", policy, "--env",
                                                 env_id, "--n-episodes", str(n)))
        if baseline["success_rate"] < 1.0:
            assert learned["success_rate"] >= baseline["success_rate"] + margin, (policy,
                                                                                  baseline)
            assert learned["success_rate"] > baseline["success_rate"], (policy, baseline)
        else:
            assert learned["success_rate"] == 1.0
            for key in keys:
                assert learned[key] < baseline[key], (policy, key)
    assert learned["success_rate"] >= floor, learned



def _v1_cases():
    for name in TARGETS_V1:
        for criterion in ("interval", "strict", "failures"):
            reason = UNMET_V1.get((name, criterion))
            marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
            yield pytest.param(name, criterion, marks=marks, id=f"{name}-{criterion}")


@pytest.mark.slow
@pytest.mark.parametrize(("name", "criterion"), list(_v1_cases()))
def test_v1_agent_meets_its_interval_precision_and_failure_targets(name, criterion,
                                                                   tmp_path_factory):
    learned: dict[str, Any] = _learned(name, Path(tmp_path_factory.getbasetemp()))
    low, strict = TARGETS_V1[name]
    if criterion == "interval":
        n = int(learned["n_episodes"])
        interval = wilson_interval(round(float(learned["success_rate"]) * n), n)
        assert low is None or interval[0] >= low, interval
    elif criterion == "strict":
        assert strict is None or learned["success_strict"] >= strict, learned["success_strict"]
    else:
        assert learned["n_failures"] == 0, learned["n_failures"]
