"""Validated range of the contact model (d_n <= 8 mm, |theta_p| <= 30 deg) and the PID units."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softhand_env.physics import stability
from softhand_env.physics.model import DN_1, TH_1, TH_OBJ, initial_state
from softhand_env.physics.motions import run_paper_motions
from softhand_env.physics.params import HandParams
from softhand_env.physics.validity import (
    VALIDATED_THETA_P,
    contact_state,
    validity_report,
    within_validated_range,
)

PARAMS = HandParams()


def test_contact_state_signs():
    y = initial_state(PARAMS)
    y[TH_1], y[TH_1 + 1], y[TH_OBJ] = 0.3, 0.1, 0.05
    y[DN_1], y[DN_1 + 1] = 0.004, 0.009
    d_n, theta_p = contact_state(np.stack([y, y]))
    np.testing.assert_array_equal(d_n, [[0.004, 0.009]] * 2)
    np.testing.assert_allclose(theta_p, [[0.25, 0.15]] * 2, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(within_validated_range(y, PARAMS), [True, False])
    y[TH_1] = VALIDATED_THETA_P + 0.05 + 1e-9
    assert not within_validated_range(y, PARAMS)[0]


def test_paper_motions_leave_the_validated_contact_angles():
    """Measured: d_n up to 7.33 mm (inside 8 mm), |theta_p| up to 42.3 deg (motion 7, beyond
    the 30 deg of the compression tests)."""
    run = run_paper_motions(PARAMS)
    report = validity_report(run.y, PARAMS)
    assert report["d_n_limit"] == pytest.approx(0.008)
    assert 7.2e-3 < report["max_d_n"] < report["d_n_limit"]
    assert 42.0 < math.degrees(report["max_theta_p"]) < 42.5
    assert not report["within"]
    first_motions = run.motion == 0
    assert validity_report(run.y[first_motions], PARAMS)["within"]


def test_pid_gains_are_per_radian():
    """Table 5.1 prints Kp = 300, Kd = 14, Ki = 0.1 without units. Read per radian (N m/rad,
    N m s/rad, N m/(rad s)) the paper's own simulation at dt = 0.1 ms is RK4-stable; read per
    degree (x 180/pi) its finger mode would be far beyond the limit, so the paper cannot have
    meant them per degree."""
    per_degree = PARAMS.replace(
        Kp=PARAMS.Kp * 180 / math.pi, Kd=PARAMS.Kd * 180 / math.pi, Ki=PARAMS.Ki * 180 / math.pi
    )
    assert stability.check_rk4_stability(PARAMS) == []
    assert "finger joint (I, Kp, Kd)" in stability.check_rk4_stability(per_degree)
