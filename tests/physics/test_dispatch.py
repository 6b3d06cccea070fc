"""Serial or parallel batched calls chosen by measured time (physics.dispatch): the choice
follows the faster mode and the machine's changes, probes back off, and HandPhysics's states
do not depend on it."""

from __future__ import annotations

import numpy as np
import pytest

from softhand_env.physics import HandPhysics
from softhand_env.physics.dispatch import ParallelChoice
from softhand_env.physics.params import HandParams


def drive(choice: ParallelChoice, cost, calls: int, hands: int = 10) -> list[bool]:
    """Run ``calls`` calls whose time is ``cost(parallel, k)`` seconds; the modes taken."""
    taken = []
    for k in range(calls):
        parallel = choice.next()
        choice.record(parallel, cost(parallel, k), hands)
        taken.append(parallel)
    return taken


def test_warm_up_alternates_and_discards_each_modes_first_call():
    choice = ParallelChoice(probes=3)
    taken = drive(choice, lambda p, k: 1.0, 8)
    assert taken == [False, True] * 4
    assert choice.samples == (3, 3)


@pytest.mark.parametrize("fast_parallel", [False, True])
def test_the_faster_mode_is_chosen(fast_parallel):
    choice = ParallelChoice(probes=3, refresh=10, max_refresh=10)

    def cost(parallel, k):
        return 1.0 if parallel == fast_parallel else 2.0

    taken = drive(choice, cost, 200)[8:]
    assert choice.preferred() == fast_parallel
    # one probe of the other mode every 10 calls, the faster mode otherwise
    assert sum(t != fast_parallel for t in taken) == len(taken) // 10


def test_first_call_of_a_mode_does_not_count():
    """A first parallel call that pays the thread pool's start (100x) is not held against it."""
    choice = ParallelChoice(probes=2)
    drive(choice, lambda p, k: (100.0 if k == 1 else 1.0) if p else 2.0, 6)
    assert choice.preferred() is True


def test_choice_follows_a_change_of_load():
    """Parallel is faster until call 300 (idle), then 10x slower (a loaded machine): the
    choice flips within a few probes and stays."""
    choice = ParallelChoice(probes=3, window=3, refresh=8, max_refresh=64)

    def cost(parallel, k):
        if parallel:
            return 1.0 if k < 300 else 20.0
        return 2.0

    taken = drive(choice, cost, 600)
    assert sum(not t for t in taken[236:300]) == 1  # one serial probe in 64 calls
    assert taken[300] and taken[301] and not any(taken[302:309])  # two slow calls flip it
    # probes of the slow mode after 8, 16, 32, 64, 64, 64 calls (248 of the 298 left)
    assert sum(taken[302:]) == 6
    assert choice.preferred() is False


def test_probes_back_off_while_they_confirm_the_choice():
    choice = ParallelChoice(probes=3, refresh=4, max_refresh=32)
    taken = drive(choice, lambda p, k: 1.0 if p else 3.0, 400)
    assert choice.interval == 32
    assert sum(not t for t in taken[200:]) <= 200 // 32 + 1


def test_times_are_per_hand():
    """A serial call of 10 hands in 10 s beats a parallel call of 1 hand in 2 s."""
    choice = ParallelChoice(probes=1)
    choice.record(False, 0.0, 10)
    choice.record(True, 0.0, 1)
    choice.record(False, 10.0, 10)
    choice.record(True, 2.0, 1)
    assert choice.preferred() is False


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="probes"):
        ParallelChoice(probes=0)
    with pytest.raises(ValueError, match="window"):
        ParallelChoice(probes=3, window=2)
    with pytest.raises(ValueError, match="max_refresh"):
        ParallelChoice(refresh=8, max_refresh=4)


@pytest.mark.parametrize("integrator", ["rk4", "ros2"])
def test_hand_physics_states_do_not_depend_on_the_mode(integrator):
    """64 hands stepped under the measured choice (both modes taken during its warm-up) and
    under serial calls only end bit for bit equal."""
    params = HandParams(integrator=integrator)
    rng = np.random.default_rng(0)
    setpoints = np.radians(rng.uniform(2.0, 12.0, (12, 64, 2)))
    chosen = HandPhysics(params, num_hands=64)
    serial = HandPhysics(params, num_hands=64)
    serial._dispatch = None  # always on the calling thread
    for u in setpoints:
        a = chosen.step(u, 100, strict=False)
        b = serial.step(u, 100, strict=False)
        np.testing.assert_array_equal(a.flags, b.flags)
    np.testing.assert_array_equal(chosen.get_state(), serial.get_state())
    assert min(chosen._dispatch.samples) >= 3  # both modes were timed
