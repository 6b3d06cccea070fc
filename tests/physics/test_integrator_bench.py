"""The integrator comparison of the speed benchmark, briefly (slow: timing on a shared machine).

The ratios are asserted, not absolute times: the median over three pairs of runs made back to
back (:func:`bench_env.compare_integrators`). The evaluation count meets its target (10x). The
wall-clock gates sit 15-20 % below the lowest pairs measured on a loaded 2-core machine (load
4-9, both OpenMP wait policies; docs/integrator.md): single env, medians 2.75-3.51, pairs
down to 2.31 (one outlier of 1.53): gate 2.0; native vector env N=512, medians 3.81-6.6, pairs
down to 3.11: gate 2.5; Random id, medians 4.7-5.3, pairs down to 3.41: gate 3.0. The
targets (4x, 8x, 10x) are figures of the full benchmark on an unloaded machine
(docs/integrator.md), not asserted here: these gates must hold on a loaded one.
"""

from __future__ import annotations

import pytest

from softhand_env.tools import bench_env


@pytest.mark.slow
def test_integrator_speed_ratios():
    seen = []
    figures = bench_env.compare_integrators(400, 512, 3, lambda *row: seen.append(row))
    assert len(seen) == 5
    by_name = {name.split(" (")[0]: fig for name, fig in figures.items()}
    assert figures["RHS evaluations per simulated s"].median >= 10.0
    assert figures["RHS evaluations per simulated s (Random ids)"].median >= 20.0
    assert by_name["single env SoftHandPose-v0"].median >= 2.0
    assert by_name["native vector env N=512"].median >= 2.5
    assert by_name["single env SoftHandPoseRandom-v0"].median >= 3.0
    for fig in figures.values():
        assert fig.low <= fig.median <= fig.high


def test_rhs_counts_of_the_comparison():
    rk4, fast = bench_env.rhs_per_simulated_second()
    assert rk4 == pytest.approx(801 / 0.02) and fast == pytest.approx(31 / 0.02)


def test_paired_figure_statistics():
    rates = bench_env.paired_rates([lambda: 2.0, lambda: 6.0], 3)
    assert rates == [[2.0] * 3, [6.0] * 3]
    fig = bench_env._figure([1.0, 2.0, 4.0], [3.0, 8.0, 4.0])
    assert (fig.rk4, fig.fast) == (2.0, 4.0)
    assert (fig.low, fig.median, fig.high) == (1.0, 3.0, 4.0)
