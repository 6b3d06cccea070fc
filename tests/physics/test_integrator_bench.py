"""The integrator comparison of the speed benchmark, briefly (slow: timing on a shared machine).

The ratios are asserted, not absolute times: the median over three pairs of runs made back to
back (:func:`bench_env.compare_integrators`). The evaluation count meets its target (10x). The
wall-clock gates sit about 25-30 % below the medians measured on a loaded 2-core machine
(load 6-9; docs/integrator.md): single env 2.8-2.9 (gate 2.0), native vector env N=512 6.1-6.6
with the OpenMP threading layer's default wait policy and 4.0 with ``OMP_WAIT_POLICY=passive``
(gate 3.0, below both), Random id 4.7-5.3 (gate 3.5). The targets of 4x, 8x and 10x are not
met.
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
    assert by_name["native vector env N=512"].median >= 3.0
    assert by_name["single env SoftHandPoseRandom-v0"].median >= 3.5
    for fig in figures.values():
        assert fig.low <= fig.median <= fig.high


def test_rhs_counts_of_the_comparison():
    rk4, fast = bench_env.rhs_per_simulated_second()
    assert rk4 == pytest.approx(801 / 0.02) and fast == pytest.approx(47 / 0.02)


def test_paired_figure_statistics():
    rates = bench_env.paired_rates([lambda: 2.0, lambda: 6.0], 3)
    assert rates == [[2.0] * 3, [6.0] * 3]
    fig = bench_env._figure([1.0, 2.0, 4.0], [3.0, 8.0, 4.0])
    assert (fig.rk4, fig.fast) == (2.0, 4.0)
    assert (fig.low, fig.median, fig.high) == (1.0, 3.0, 4.0)
