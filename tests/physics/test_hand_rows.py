"""Row-wise pieces of HandPhysics (read-outs and restarts of some hands), the step's skip
argument, and HandParams as a dictionary key (its hash is computed once)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from softhand_env.physics import HandPhysics
from softhand_env.physics.hand import READ_SIZE
from softhand_env.physics.params import HandParams


def _stepped(n: int) -> HandPhysics:
    """n hands with different parameters after one step to different set-points."""
    hand = HandPhysics(HandParams(), num_hands=n)
    for i in range(n):
        hand.set_params(HandParams(E=0.2e6 + 1e4 * i, mu=0.5 + 0.1 * i), i)
    rng = np.random.default_rng(3)
    hand.step(hand.finger_angles + rng.uniform(-0.02, 0.02, (n, 2)), 100, strict=False)
    return hand


def test_read_into_rows_writes_those_rows_as_readouts_does_and_no_other():
    hand = _stepped(5)
    full = np.empty((5, READ_SIZE))
    hand.read_into(full)
    r = hand.readouts()
    np.testing.assert_array_equal(full[:, :3], r.object_pose)
    np.testing.assert_array_equal(full[:, -2:], r.joint_torques)
    block = np.full((5, READ_SIZE), -7.0)
    hand.read_into(block, np.array([1, 3]))
    np.testing.assert_array_equal(block[[1, 3]], full[[1, 3]])
    assert (block[[0, 2, 4]] == -7.0).all()


def test_reset_hands_equals_reset_hand_row_by_row():
    a, b = _stepped(4), _stepped(4)
    rows = np.array([2, 0])
    states = a.get_state()[[1, 3]] * 1.0
    setpoints = np.array([[0.1, 0.2], [0.3, -0.1]])
    params = [HandParams(E=0.3e6), a.params[0]]
    a.reset_hands(rows, states, setpoints, params)
    for k, i in enumerate(rows):
        b.reset_hand(int(i), states[k], setpoints[k], params[k])
    np.testing.assert_array_equal(a.get_state(), b.get_state())
    np.testing.assert_array_equal(a.setpoint, b.setpoint)
    np.testing.assert_array_equal(a.packed_params, b.packed_params)
    assert a.params == b.params


@pytest.mark.parametrize("skip", [[False, True, False], np.zeros(2, dtype=bool),
                                  np.zeros(3, dtype=int)])
def test_step_refuses_a_skip_that_is_not_a_bool_array_per_hand(skip):
    hand = _stepped(3)
    with pytest.raises(ValueError, match="skip must be a bool array of shape"):
        hand.step(hand.setpoint, 10, strict=False, skip=skip)


def test_a_skipped_hand_is_untouched_and_reads_flags_0_not_grasped():
    hand = _stepped(3)
    before = hand.get_state()
    skip = np.array([False, True, False])
    status = hand.step(hand.setpoint + 0.01, 50, strict=False, skip=skip)
    after = hand.get_state()
    np.testing.assert_array_equal(after[1], before[1])
    assert not np.array_equal(after[0], before[0])
    assert status.flags[1] == 0 and not status.failed[1] and not status.grasped[1]


def test_params_hash_is_that_of_equal_params_and_survives_replace_and_pickle():
    p = HandParams()
    q = p.replace(E=0.3e6, mu=0.7)
    fresh = HandParams(E=0.3e6, mu=0.7)
    assert hash(p) == hash(HandParams()) and q == fresh and hash(q) == hash(fresh)
    assert hash(q.replace(E=p.E, mu=p.mu)) == hash(p)
    # the cached hash does not travel: str hashes differ between processes
    hash(q)
    assert "_hash" not in pickle.loads(pickle.dumps(q)).__dict__
    assert pickle.loads(pickle.dumps(q)) == q
    assert {p: 1}[HandParams()] == 1


@pytest.mark.parametrize("field, value", [("E", float("nan")), ("E", -1.0), ("dt", 0.5),
                                          ("c_n", float("inf")), ("integrator", "euler")])
def test_replace_checks_each_changed_field(field, value):
    with pytest.raises(ValueError, match=field):
        HandParams().replace(**{field: value})
