"""Episode starts of K environments at once (``start.start_episodes``): the K grasp phases of
randomised starts run in one batched physics, with the same draws and numbers as
``start.start_episode`` row by row, redraws of failed grasp phases and their error included."""

from __future__ import annotations

import numpy as np
import pytest

from softhand_env.envs import start
from softhand_env.envs.config import build_config
from softhand_env.envs.options import EnvOptions
from softhand_env.physics.hand import PhysicsError

#: wide grasp noise and stiffness: about half of the grasp phases fail and are redrawn
#: (measured: 87 grasp phases for 40 episodes)
REDRAWING = dict(task="pose", reset_noise_deg=10.0, rand_stiffness=0.2, setpoint_latency=2)


def _generators(k):
    return [np.random.default_rng(100 + j) for j in range(k)]


def test_batched_starts_equal_single_starts_with_redraws(monkeypatch):
    cfg = build_config(EnvOptions(**REDRAWING))
    batches = []
    original = start.grasp_states

    def counting(params, *args, **kwargs):
        batches.append(len(params))
        return original(params, *args, **kwargs)

    monkeypatch.setattr(start, "grasp_states", counting)
    rngs = _generators(12)
    goals = [np.zeros(2)] * 12  # given goals: still drawn, then replaced
    goals[3] = np.array([0.002, 0.05])
    batch = start.start_episodes(cfg, rngs, goals)
    assert len(batches) > 1 and batches[0] == 12  # failed grasp phases were redrawn
    single_rngs = _generators(12)
    singles = [start.start_episode(cfg, rng, g)
               for rng, g in zip(single_rngs, goals, strict=True)]
    np.testing.assert_array_equal(batch.state, [s.state for s in singles])
    np.testing.assert_array_equal(batch.setpoint, [s.setpoint for s in singles])
    np.testing.assert_array_equal(batch.goal, [s.goal for s in singles])
    np.testing.assert_array_equal(batch.latency, [s.latency for s in singles])
    assert batch.params == [s.params for s in singles]
    np.testing.assert_array_equal(batch.mu, [s.params.mu for s in singles])
    np.testing.assert_array_equal(batch.radius, [s.params.a for s in singles])
    # every generator is left where the single start leaves it
    assert [r.random() for r in rngs] == [r.random() for r in single_rngs]


def test_batched_starts_raise_the_single_start_error(monkeypatch):
    monkeypatch.setattr(start, "MAX_DRAWS", 1)  # the first failed grasp phase raises
    cfg = build_config(EnvOptions(**REDRAWING))
    with pytest.raises(PhysicsError) as single:
        for rng in _generators(12):
            start.start_episode(cfg, rng)
    with pytest.raises(PhysicsError) as batch:
        start.start_episodes(cfg, _generators(12))
    assert str(batch.value) == str(single.value) and "grasp phase" in str(batch.value)
    assert batch.value.flags == single.value.flags
