"""Serial or parallel batched kernel calls, chosen by measured time.

A batched kernel call (:func:`softhand_env.physics.kernel.advance_batch`,
:func:`softhand_env.physics.rosenbrock.advance_batch`) can run its blocks of hands one after the
other on the calling thread or over numba's threads. Both give the same numbers bit for bit
(a block's arithmetic does not depend on the thread that runs it); only the time differs, and
which is faster depends on the machine as much as on the work. On an idle 2-core machine 512
hands under ROS2 (about 1.4 ms of work a control step) run about 1.6x faster in parallel; on a
loaded one a parallel region waits for a descheduled worker thread (15-25 ms measured with
the OpenMP threading layer's default wait policy), twenty times that work. No fixed threshold
is right on both, so :class:`HandPhysics <softhand_env.physics.hand.HandPhysics>` measures
(:class:`ParallelChoice`):

* after one untimed call of each mode (compilation, the thread pool's start), the next
  ``probes`` calls of each mode are timed in turn, serial first;
* then every call takes the mode whose median time per hand over its last ``window`` timed
  calls is the smaller, and now and then the other mode runs once (a probe), so that its
  estimate follows the machine's load: after ``refresh`` calls, and after twice as many each
  time a probe confirms the choice (at most ``max_refresh``), back to ``refresh`` when the
  choice changes. A probe of the slow mode on a loaded machine therefore costs little on
  average.

Times are per advanced hand (a call's wall time divided by the hands it advanced), so calls
with skipped hands compare with full ones. The choice changes the speed only, never a number.
"""

from __future__ import annotations

from collections import deque
from statistics import median


class ParallelChoice:
    """Chooses serial or parallel execution of repeated batched calls by their measured time.

    Parameters
    ----------
    probes : int
        Timed calls of each mode taken in turn before the first choice, >= 1.
    window : int
        Recent timed calls per mode whose median time per hand decides, >= ``probes``.
    refresh : int
        Calls between probes of the mode not chosen after a change of choice, >= 1.
    max_refresh : int
        Longest interval between probes (calls), >= ``refresh``.

    Use::

        parallel = choice.next()
        t0 = time.perf_counter()
        ...  # the call, on numba's threads if parallel else on this one
        choice.record(parallel, time.perf_counter() - t0, hands)
    """

    def __init__(self, probes: int = 3, window: int = 5, refresh: int = 32,
                 max_refresh: int = 2048):
        if probes < 1 or window < probes or refresh < 1 or max_refresh < refresh:
            raise ValueError(
                "need probes >= 1, window >= probes, refresh >= 1 and max_refresh >= refresh "
                f"(got {probes}, {window}, {refresh}, {max_refresh})"
            )
        self.probes = probes
        self.window = window
        self.refresh = refresh
        self.max_refresh = max_refresh
        self._times: tuple[deque[float], deque[float]] = (deque(maxlen=window),
                                                          deque(maxlen=window))
        self._seen = [0, 0]
        self._interval = refresh
        self._since = 0
        self._probe = False
        self._preferred = False  # preferred(), updated by every timed record

    def next(self) -> bool:
        """True if the next call should run in parallel."""
        serial, parallel = self._times
        if len(serial) < self.probes or len(parallel) < self.probes:
            return self._seen[1] < self._seen[0]
        best = self.preferred()
        self._since += 1
        if self._since >= self._interval:
            self._since = 0
            self._probe = True
            return not best
        return best

    def preferred(self) -> bool:
        """The mode with the smaller median time per hand so far (serial on a tie or while a
        mode has no timed call)."""
        return self._preferred

    def _median_choice(self) -> bool:
        serial, parallel = self._times
        if not serial or not parallel:
            return False
        return median(parallel) < median(serial)

    def record(self, parallel: bool, seconds: float, hands: int) -> None:
        """Record a call that took ``seconds`` (s) in the mode ``parallel`` and advanced
        ``hands`` hands (a call of no hand is not timed)."""
        mode = int(bool(parallel))
        self._seen[mode] += 1
        if hands >= 1 and self._seen[mode] > 1:  # the first call of a mode pays its start
            before = self._preferred
            self._times[mode].append(seconds / hands)
            self._preferred = self._median_choice()
            if self._preferred != before:  # the load changed: probe soon again
                self._interval = self.refresh
                self._since = 0
            elif self._probe:  # a probe confirmed the choice: probe less often
                self._interval = min(2 * self._interval, self.max_refresh)
        self._probe = False

    @property
    def interval(self) -> int:
        """Calls between probes of the mode not chosen, now."""
        return self._interval

    @property
    def samples(self) -> tuple[int, int]:
        """Timed calls kept for the serial and the parallel mode."""
        return len(self._times[0]), len(self._times[1])


__all__ = ["ParallelChoice"]
