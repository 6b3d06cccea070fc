"""The ``contact`` figure command writes the four PNGs of Figs 2.6, 2.7, 2.11 and 3.3."""

from __future__ import annotations

import argparse

import pytest

from softhand_env.figures import contact as fig_contact
from softhand_env.figures import main

EXPECTED = {
    "fig2_6_stiffness.png",
    "fig2_7_force_energy.png",
    "fig2_11_force_vs_angle.png",
    "fig3_3_nonlinear_force.png",
}


def test_contact_command_writes_four_pngs(tmp_path, capsys):
    out = tmp_path / "nested" / "figs"  # created by the command
    assert main(["contact", "--out", str(out), "--dpi", "60"]) == 0
    printed = capsys.readouterr().out.split()
    assert {p.rsplit("/", 1)[-1] for p in printed} == EXPECTED
    for name in EXPECTED:
        data = (out / name).read_bytes()
        assert len(data) > 1000 and data[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_returns_paths_and_rejects_bad_dpi(tmp_path):
    with pytest.raises(ValueError, match="dpi must be > 0"):
        fig_contact.run(argparse.Namespace(out=str(tmp_path), dpi=0))
    parser = argparse.ArgumentParser()
    fig_contact.add_arguments(parser)
    assert parser.parse_args([]).dpi == 150
