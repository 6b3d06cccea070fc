"""Learning-curve figure from run directories (agents.learning_curves)."""

from __future__ import annotations

import numpy as np
import pytest

from agents import learning_curves
from agents.common.cli import UserError


def test_reads_ppo_and_dagger_runs_and_draws_both_panels(tmp_path):
    ppo, dag = tmp_path / "ppo_run", tmp_path / "dagger_run"
    ppo.mkdir()
    dag.mkdir()
    np.savez(ppo / "evaluations.npz", timesteps=np.array([100, 200]),
             successes=np.array([[0, 0, 1, 0], [1, 1, 1, 0]]), results=np.zeros((2, 4)))
    np.savez(dag / "dagger_curve.npz", env_steps=np.array([10, 20, 30]),
             success_rate=np.array([0.1, 0.5, 0.9]))
    trainer, steps, success = learning_curves.read_curve(ppo)
    assert trainer == "ppo"
    np.testing.assert_allclose(success, [0.25, 0.75])
    assert learning_curves.read_curve(dag)[0] == "dagger"
    out = learning_curves.main([str(ppo), str(dag), "--out", str(tmp_path / "c.png")])
    assert out.stat().st_size > 1000
    with pytest.raises(UserError, match="exists"):
        learning_curves.main([str(ppo), "--out", str(out)])
    with pytest.raises(UserError, match="neither"):
        learning_curves.main([str(tmp_path), "--out", str(tmp_path / "d.png")])
    with pytest.raises(UserError, match=".png"):
        learning_curves.main([str(ppo), "--out", str(tmp_path / "d.pdf")])
