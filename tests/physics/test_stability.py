"""A-priori RK4 stability check (softhand_env.physics.stability), including the finger/PID modes.

The check linearises the model at symmetric grasp states and tests |R(dt lambda)| <= 1 for
every decaying eigenvalue. It must flag parameter sets that really diverge at dt = 0.1 ms
(Kd = 21 and 28, 1.5 and 2 times the paper's 14) and pass the paper's gains and the same
gains at dt = 0.05 ms, where they run cleanly.
"""

from __future__ import annotations

import numpy as np
import pytest

from softhand_env.envs.randomization import FIELDS, PRESET
from softhand_env.physics import HandPhysics, kernel, stability
from softhand_env.physics.motions import PAPER_MOTIONS_DEG, run_paper_motions, run_setpoint_sequence
from softhand_env.physics.params import HandParams, load_hand_params

PARAMS = HandParams()
FINGER = "finger joint (I, Kp, Kd)"


def test_rk4_real_axis_limit():
    amp = stability.rk4_amplification
    assert amp(-2.78) < 1.0 < amp(-2.79)
    assert amp(0.0) == 1.0
    assert amp(-1e-3) == pytest.approx(np.exp(-1e-3), abs=1e-14)


@pytest.mark.parametrize("name", ["paper_ch5", "paper_ch4"])
def test_paper_parameters_are_stable(name):
    params = load_hand_params(name)
    assert stability.check_rk4_stability(params) == []
    margins = stability.rk4_stability_margins(params)
    assert margins["holonomic (alpha)"] == pytest.approx(2.0)
    assert margins[FINGER] < 1.0  # measured 0.84


def test_jacobian_spectrum_contains_the_baumgarte_roots():
    """Independent of the mode naming: the linearised CSM carries -alpha (double) and -beta
    (twice, one per rolling constraint) as eigenvalues."""
    y, u = stability.probe_states(PARAMS)[-1]
    lam = np.linalg.eigvals(stability.jacobian(PARAMS, y, u))
    for root, count in ((-PARAMS.alpha, 4), (-PARAMS.beta, 2)):
        assert np.sum(np.abs(lam - root) < 0.01 * abs(root)) == count


@pytest.mark.parametrize("Kd,expected", [(14.0, False), (17.5, False), (21.0, True), (28.0, True)])
def test_finger_damping_mode_is_checked(Kd, expected):
    params = PARAMS.replace(Kd=Kd)
    assert (FINGER in stability.check_rk4_stability(params)) is expected
    # the same gains at half the step are inside the limit
    assert stability.check_rk4_stability(params.replace(dt=5e-5)) == []


def test_flagged_gains_really_diverge_and_unflagged_ones_do_not():
    """Kd = 21 at dt = 0.1 ms: the 6 deg grasp is stopped by a fatal flag within 0.3 s
    (the divergence first shows as a lost grasp); at dt = 0.05 ms, and with Kd = 14, it holds."""

    def survives(params):
        physics = HandPhysics(params)
        n = round(0.3 / params.dt)
        return not physics.step(np.radians([6.0, 6.0]), n, strict=False).fatal

    with pytest.warns(RuntimeWarning, match="finger joint"):
        assert not survives(PARAMS.replace(Kd=21.0))
    assert survives(PARAMS.replace(Kd=21.0, dt=5e-5))
    assert survives(PARAMS)


@pytest.mark.filterwarnings("ignore:RK4 step")
def test_flagged_through_the_margin_and_really_divergent():
    """Gains x1.2 with object mass x0.8 pass the probe states by 1 % (|lambda| dt = 2.755) but
    need 2.79 at the theta_p = 42 deg of motion 7: the 5 % step margin flags them, and the
    paper's motions at dt = 0.1 ms indeed diverge (a fatal flag at 6.27 s, in motion 7:
    constraint violation and lost grasp; strict=False so the run reports it rather than
    raising), while at dt = 0.05 ms they complete."""
    params = PARAMS.replace(Kp=360.0, Kd=16.8, Ki=0.12, M_obj=0.24)
    margins = stability.rk4_stability_margins(params)
    assert 2.7 < margins[FINGER] < stability.RK4_REAL_STABILITY
    assert FINGER in stability.check_rk4_stability(params)
    run = run_setpoint_sequence(
        np.radians(PAPER_MOTIONS_DEG), params, record_interval=0.02, strict=False
    )
    assert run.flags[-1] & kernel.FATAL_FLAGS and run.motion[-1] == 6
    half = params.replace(dt=5e-5)
    assert stability.check_rk4_stability(half) == []
    assert not np.any(run_paper_motions(half, record_interval=0.02).flags & kernel.FATAL_FLAGS)


def test_warning_and_error_name_the_mode_and_the_step():
    params = PARAMS.replace(Kd=28.0)
    match = r"dt = 0\.0001 s .*finger joint.*\|lambda\| dt = 3\.85"
    with pytest.warns(RuntimeWarning, match=match):
        HandPhysics(params)
    with pytest.raises(ValueError, match="finger joint"):
        stability.warn_if_unstable(params, error=True)
    stability.warn_if_unstable(PARAMS, error=True)  # no error


def test_stiff_bending_is_named():
    assert "bending" in stability.check_rk4_stability(PARAMS.replace(bending=1e5, g=0.0))


def test_randomisation_presets_pass():
    stability.check_randomization_ranges(PARAMS, FIELDS, PRESET)
    stability.check_randomization_ranges(PARAMS, FIELDS, {})


def test_randomisation_extremes_beyond_the_limit_are_refused():
    """rand_gains 0.5 alone: Kd x1.5 = 21 at one corner (diverges, see above); the limit the
    message states (0.374) is where the check changes its verdict."""
    with pytest.raises(ValueError, match=r"rand_gains \+0\.5.*finger joint.*rand_gains <= 0\.374"):
        stability.check_randomization_ranges(PARAMS, FIELDS, {"rand_gains": 0.5})
    stability.check_randomization_ranges(PARAMS, FIELDS, {"rand_gains": 0.37})
    with pytest.raises(ValueError, match="rand_gains"):
        stability.check_randomization_ranges(PARAMS, FIELDS, {"rand_gains": 0.38})
    # with the preset mass range (-20 %) the gains range must be smaller
    with pytest.raises(ValueError, match=r"rand_mass -0\.2.*rand_gains \+0\.3"):
        stability.check_randomization_ranges(PARAMS, FIELDS, {**PRESET, "rand_gains": 0.3})
