"""SIGINT and SIGTERM deferred to a safe point: how ``agents.train`` and ``agents.distill`` stop.

A signal that raises where it lands can leave a run half written, and inside the numba
kernel numba may turn the ``KeyboardInterrupt`` into a ``SystemError`` that gets past
``except KeyboardInterrupt``. So while :meth:`DeferredSignals.installed` is active, SIGINT and
SIGTERM only set a flag (the handler runs between Python bytecodes, never inside compiled
code); the trainer looks at the flag at its safe points (between env steps, between
minibatches) and stops there, then saves and finalises the run as at a normal end, with
``interrupted: true`` in its record. :class:`StopOnSignal` is the flag as an SB3 callback
(``learn()`` returns after the step at which the flag is seen).
"""

from __future__ import annotations

import contextlib
import signal
import sys
from collections.abc import Iterator
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback


class Interrupted(Exception):
    """Raised by :meth:`DeferredSignals.check` at a safe point once a signal was received."""


class DeferredSignals:
    """A flag set by SIGINT or SIGTERM while :meth:`installed` is active.

    Parameters
    ----------
    what : str
        What stops, for the one stderr line printed on the first signal (e.g. ``"training"``).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, what: str = "training") -> None:
        self.what = what
        #: Name of the first signal received (``"SIGINT"``, ``"SIGTERM"``), None if none.
        self.signal_name: str | None = None

    def _handle(self, signum: int, frame: Any) -> None:
        name = signal.Signals(signum).name
        if self.signal_name is None:
            self.signal_name = name
            print(f"{name}: {self.what} stops at the next safe point; the run is saved",
                  file=sys.stderr, flush=True)

    @property
    def received(self) -> bool:
        """Whether a signal was received."""
        return self.signal_name is not None

    def check(self) -> None:
        """Raise :class:`Interrupted` if a signal was received (call at a safe point)."""
        if self.signal_name is not None:
            raise Interrupted(self.signal_name)

    @contextlib.contextmanager
    def installed(self) -> Iterator[DeferredSignals]:
        """Install the flag-setting handlers (main thread only) for the ``with`` block; the
        previous handlers are restored on leaving it."""
        previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        try:
            yield self
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)


class StopOnSignal(BaseCallback):
    """SB3 callback that ends ``learn()`` cleanly once ``signals`` has received a signal: its
    ``_on_step`` (after each env step, outside the physics kernel and any file write) returns
    False and SB3 leaves ``learn()``.

    Parameters
    ----------
    signals : DeferredSignals
        The flag (its handlers installed by the caller).
    """

    def __init__(self, signals: DeferredSignals) -> None:
        super().__init__()
        self.signals = signals

    def _on_step(self) -> bool:
        return not self.signals.received
