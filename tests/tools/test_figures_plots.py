"""Readability of the reproduced figures: Fig 2.6 shows all four theta_p series, Fig 5.6 has
no solid round-off bands."""

from __future__ import annotations

import numpy as np

from softhand_env.figures import contact as fig_contact
from softhand_env.figures import dynamics as fig_dynamics


def test_fig_2_6_shows_every_theta_p_series_apart():
    fig = fig_contact._new_figure(ncols=2)
    fig_contact._fig_2_6(fig)
    ax_k, ax_err = fig.axes
    numeric = [ln for ln in ax_k.get_lines() if "numerical" in ln.get_label()]
    assert len(numeric) == len(fig_contact.ANGLES_DEG) == 4
    xs = [set(np.round(ln.get_xdata(), 9)) for ln in numeric]
    for i in range(4):
        for j in range(i + 1, 4):
            assert not xs[i] & xs[j]  # staggered in d: no marker hides another
    assert len({ln.get_marker() for ln in numeric}) == 4
    errors = [ln for ln in ax_err.get_lines() if ln.get_label().startswith("$\\theta_p")]
    assert len(errors) == 4 and len({ln.get_linestyle() for ln in errors}) == 4
    for ln in errors:  # numerical vs closed form: round-off, plotted in units of 1e-15
        assert np.all(np.abs(ln.get_ydata()) < 100)
    assert "coincide" in ax_k.get_title()


def test_fig_5_6_draws_values_below_round_off_on_the_floor():
    t = np.arange(200) * 1e-3
    res = np.zeros((200, 4))
    res[::2] = 3e-18  # what the integrator leaves at rest: alternating round-off and exact 0
    res[50] = [1e-9, 2e-9, 1e-7, 2e-7]
    fig = fig_dynamics.constraint_figure(t, res, 2e4, 1e4)
    assert "= 2e+04 1/s" in fig._suptitle.get_text()
    for k, ax in enumerate(fig.axes):
        (curve,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == len(t)]
        y = curve.get_ydata()
        assert y.min() == fig_dynamics.ROUNDOFF_FLOOR
        assert np.count_nonzero(y > fig_dynamics.ROUNDOFF_FLOOR) == 1  # only the real spike
        assert ax.get_ylim()[0] < fig_dynamics.ROUNDOFF_FLOOR
        paper = fig_dynamics.PAPER_LEVEL_CH if k in (0, 2) else fig_dynamics.PAPER_LEVEL_CN
        assert any(np.allclose(ln.get_ydata(), paper) for ln in ax.get_lines()
                   if ln.get_linestyle() == "--")
