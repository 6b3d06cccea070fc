"""Evaluation protocol: Wilson intervals of success rates, the strict success rule, the
test-goal counter of a run (agents.evaluate, agents.play.test_scores)."""

from __future__ import annotations

import json
import math
import re
import shutil

import pytest
import yaml

from agents import evaluate
from agents.common import metrics
from agents.common.metrics import is_failure, strict_success, success_text, wilson_interval
from agents.play import test_scores
from agents.play.rollout import summarize_episodes, summary_yaml
from agents.runs import loading
from agents.runs.layout import MODELS_DIR, TEST_SCORES_FILE
from agents.runs.loading import shipped_models

Z = 1.959963984540054


def _score_test_bound(k: int, n: int, upper: bool) -> float:
    """Reference bound, computed without the closed form: the rate p at which the score test
    |k/n - p| = z sqrt(p (1 - p) / n) turns from accepting to rejecting, by bisection."""
    p_hat = k / n

    def accepts(p: float) -> bool:
        return abs(p_hat - p) <= Z * math.sqrt(p * (1 - p) / n)

    lo, hi = (p_hat, 1.0) if upper else (0.0, p_hat)
    if (upper and accepts(1.0)) or (not upper and accepts(0.0)):
        return 1.0 if upper else 0.0
    for _ in range(200):  # accepts(inner end) is True, accepts(outer end) False
        mid = 0.5 * (lo + hi)
        if accepts(mid) == upper:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("k,n", [(86, 100), (1, 10), (5, 10), (290, 300), (255, 300),
                                 (99, 100), (3, 7)])
def test_wilson_interval_inverts_the_score_test(k, n):
    low, high = wilson_interval(k, n)
    assert low == pytest.approx(_score_test_bound(k, n, upper=False), abs=1e-12)
    assert high == pytest.approx(_score_test_bound(k, n, upper=True), abs=1e-12)
    assert 0.0 <= low < k / n < high <= 1.0
    # the interval of the failures is the mirror image
    f_low, f_high = wilson_interval(n - k, n)
    assert (f_low, f_high) == pytest.approx((1 - high, 1 - low), abs=1e-12)


def test_wilson_interval_known_values():
    # worked by hand: 86 / 100, z^2 = 3.841459; centre = (0.86 + 0.019207) / 1.038415 = 0.846682,
    # half = 1.959964 / 1.038415 * sqrt(0.86 * 0.14 / 100 + 3.841459 / 40000) = 0.068054
    assert wilson_interval(86, 100) == pytest.approx((0.778628, 0.914737), abs=2e-6)
    # 0 / n and n / n: closed forms z^2 / (n + z^2) and n / (n + z^2), the other end exact
    z2 = Z * Z
    assert wilson_interval(0, 100) == (0.0, pytest.approx(z2 / (100 + z2), rel=1e-12))
    assert wilson_interval(100, 100) == (pytest.approx(100 / (100 + z2), rel=1e-12), 1.0)
    assert wilson_interval(300, 300)[0] == pytest.approx(0.98735, abs=1e-5)
    assert wilson_interval(1, 1) == (pytest.approx(1 / (1 + z2)), 1.0)
    # a wider z gives a wider interval
    assert wilson_interval(86, 100, z=2.576)[0] < wilson_interval(86, 100)[0]


@pytest.mark.parametrize("k,n", [(0, 0), (1, 0), (-1, 10), (11, 10), (1.5, 10), (1, 2.5)])
def test_wilson_interval_refuses_bad_counts(k, n):
    with pytest.raises(ValueError):
        wilson_interval(k, n)


def test_success_text_shows_count_and_interval():
    assert success_text(86, 100) == "86.0 % (86/100, 95 % CI 77.9-91.5 %)"
    assert success_text(0, 3).startswith("0.0 % (0/3, 95 % CI 0.0-")
    with pytest.raises(ValueError):
        metrics.success_count(0.505, 100)


def test_strict_success_needs_the_success_and_half_the_tolerance():
    both = ("x", "theta")
    assert strict_success(True, {"x_mm": 0.49, "theta_deg": 0.2}, both)
    assert not strict_success(True, {"x_mm": 0.5, "theta_deg": 0.2}, both)
    assert not strict_success(True, {"x_mm": 0.1, "theta_deg": 0.7}, both)
    assert not strict_success(False, {"x_mm": 0.1, "theta_deg": 0.1}, both)  # a failed step
    assert strict_success(True, {"theta_deg": 0.3}, ("theta",))
    assert strict_success(True, {}, ()) and not strict_success(False, {}, ())


def test_a_failure_is_an_ending_other_than_the_time_limit_or_success():
    from softhand_env.physics.failure import REASONS

    assert not is_failure(None) and not is_failure("success")
    for reason in (*REASONS, "slip", "tension"):
        assert is_failure(reason)


def test_results_summary_carries_both_intervals():
    out = summary_yaml({"n_episodes": 10, "success_rate": 0.9, "success_strict": 0.5,
                        "median_x_mm": 0.2})
    assert list(out)[:5] == ["n_episodes", "success_rate", "success_ci95", "success_strict",
                             "success_strict_ci95"]
    assert out["success_ci95"] == list(wilson_interval(9, 10))
    assert out["success_strict_ci95"] == list(wilson_interval(5, 10))


def test_strict_rate_is_computed_from_the_recorded_final_errors():
    def ep(success, x_mm, theta_deg):
        return {"success": success, "errors": {"x_mm": x_mm, "theta_deg": theta_deg},
                "return": 1.0, "length": 50, "termination_reason": None,
                "max_friction_ratio": 0.1}

    records = [ep(True, 0.1, 0.1), ep(True, 0.6, 0.1), ep(True, 0.2, 0.9),
               ep(False, 0.1, 0.1)]
    for r in records:
        r["success_strict"] = strict_success(r["success"], r["errors"], ("x", "theta"))
    summary = summarize_episodes(records, ("x", "theta"))
    assert summary["success_rate"] == 0.75 and summary["success_strict"] == 0.25
    pose = evaluate.format_table("t", summary, ("x", "theta"))
    assert re.search(r"success rate \(1 mm / 1 deg\) +75.0 % \(3/4", pose)
    assert re.search(r"success rate, strict \(0.5 mm / 0.5 deg\) +25.0 % \(1/4", pose)
    translate = evaluate.format_table("t", {**summary, "success_strict": 0.5}, ("x",))
    assert re.search(r"success rate \(1 mm\) +75.0 %", translate)
    assert re.search(r"strict \(0.5 mm\) +50.0 % \(2/4", translate)
    assert "deg" not in translate.split("final")[0]
    assert evaluate.tolerance_text(("theta",), strict=True) == "0.5 deg"


def test_what_counts_as_a_test_score():
    assert test_scores.plays_test_goals(10000, 1, None)
    assert test_scores.plays_test_goals(9990, 20, None)  # meets seed 10000
    assert test_scores.plays_test_goals(10300, 5, None)
    assert not test_scores.plays_test_goals(5000, 100, None)  # the validation goals
    assert not test_scores.plays_test_goals(5000, 5000, None)
    assert not test_scores.plays_test_goals(10000, 100, "goals.json")  # given goals
    assert test_scores.is_shipped(MODELS_DIR / "ppo" / "SoftHandTranslate-v0_1")
    assert not test_scores.is_shipped(MODELS_DIR.parent.parent / "logs")


def _run_copy(tmp_path):
    src = shipped_models()["SoftHandTranslate-v0"].parent
    dst = tmp_path / "ppo" / "SoftHandTranslate-v0_1"
    shutil.copytree(src, dst)
    return dst


def _scores(run):
    return yaml.safe_load((run / TEST_SCORES_FILE).read_text())


def test_evaluate_counts_test_scores_of_a_run_and_keeps_its_checksums(tmp_path, capsys):
    run = _run_copy(tmp_path)
    common = ["--model", str(run), "--n-episodes", "2", "--no-plots"]
    s1 = evaluate.main([*common, "--out", str(tmp_path / "a")])  # default seed: test goals
    printed = capsys.readouterr().out
    assert "95 % CI" in printed and "success rate, strict (0.5 mm)" in printed
    assert "scored on them once" in printed
    data = _scores(run)
    assert data["count"] == 1 and len(data["scores"]) == 1
    entry = data["scores"][0]
    assert entry["n_episodes"] == 2 and entry["first_seed"] == 10000
    assert entry["success"] == s1["success_rate"] and entry["model"] == run.name[:-2] + ".zip"
    assert entry["success_strict"] == s1["success_strict"]
    results = yaml.safe_load((tmp_path / "a" / "results.yml").read_text())
    k = round(s1["success_rate"] * 2)
    assert results["summary"]["success_ci95"] == list(wilson_interval(k, 2))
    assert "success_strict_ci95" in results["summary"]

    evaluate.main([*common, "--seed", "10002", "--out", str(tmp_path / "b")])
    assert "scored on them 2 times" in capsys.readouterr().out
    assert _scores(run)["count"] == 2
    assert [e["first_seed"] for e in _scores(run)["scores"]] == [10000, 10002]
    loading.ModelPolicy(run)  # the checksums in config.yml still hold


def test_validation_goals_and_goal_files_are_not_counted(tmp_path, capsys):
    run = _run_copy(tmp_path)
    common = ["--model", str(run), "--n-episodes", "2", "--no-plots"]
    evaluate.main([*common, "--seed", "5000", "--out", str(tmp_path / "a")])
    goals = tmp_path / "goals.json"
    goals.write_text(json.dumps([0.002, -0.002]))
    evaluate.main(["--model", str(run), "--goals", str(goals), "--no-plots",
                   "--out", str(tmp_path / "b")])
    assert "test goals" not in capsys.readouterr().out.split("results.yml")[-1]
    assert not (run / TEST_SCORES_FILE).exists()


def test_shipped_models_are_not_written_to(tmp_path, capsys):
    before = sorted(p for p in MODELS_DIR.rglob("*") if p.is_file())
    evaluate.main(["--model", "SoftHandTranslate-v0", "--n-episodes", "1", "--no-plots",
                   "--out", str(tmp_path / "a")])
    assert "shipped model: its test scores are documented in docs/results.md" in (
        capsys.readouterr().out)
    assert sorted(p for p in MODELS_DIR.rglob("*") if p.is_file()) == before
    assert not list(MODELS_DIR.rglob(TEST_SCORES_FILE))
    run = shipped_models()["SoftHandTranslate-v0"].parent
    with pytest.raises(ValueError, match="shipped"):
        test_scores.record_score(run, "x.zip", 1, 10000, {"success_rate": 1.0})


def test_a_corrupt_score_record_is_refused(tmp_path):
    run = _run_copy(tmp_path)
    (run / TEST_SCORES_FILE).write_text("count: 3\nscores: []\n")
    with pytest.raises(evaluate.UserError, match="not a test-score record"):
        test_scores.record_score(run, "x.zip", 1, 10000, {"success_rate": 1.0})
    with pytest.raises(evaluate.UserError, match="not a test-score record"):  # before playing
        evaluate.main(["--model", str(run), "--n-episodes", "1", "--no-plots",
                       "--out", str(tmp_path / "a")])
    assert not (tmp_path / "a").exists()
