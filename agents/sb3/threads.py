"""Torch threads by phase: few while the environments are stepped, more while the networks fit.

On a small machine the batched physics (numba threads, one per core) and torch share the
cores. During a rollout the physics runs and torch only evaluates the policy on one batch per
step, so torch is best left on one thread (more would compete with the physics threads);
between rollouts the physics is idle and the fit (PPO's epochs, DAgger's minibatches) is
matrix products that a second thread speeds up. ``agents.train --fit-threads`` and
``agents.distill --fit-threads`` switch torch's thread count at those boundaries:
:class:`PhaseThreads` as an SB3 callback (``on_rollout_start`` / ``on_rollout_end``, between
which SB3 steps the envs and after which it fits), :func:`fitting_threads` around a fit loop.
Only the speed is meant to change; since a matrix product's last bits may depend on the
thread count on some machines or builds, a run is promised to repeat for the same pair of
counts.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch
from stable_baselines3.common.callbacks import BaseCallback


@contextlib.contextmanager
def fitting_threads(fit: int) -> Iterator[None]:
    """Run the block with ``fit`` torch threads (>= 1), then restore the previous count."""
    before = torch.get_num_threads()
    torch.set_num_threads(fit)
    try:
        yield
    finally:
        torch.set_num_threads(before)


class PhaseThreads(BaseCallback):
    """SB3 callback: ``rollout`` torch threads while the envs are stepped (and validated,
    which happens inside the rollout), ``fit`` threads from the end of a rollout until the
    next one starts (the algorithm's update).

    Parameters
    ----------
    rollout, fit : int
        Torch threads of the two phases, >= 1.
    """

    def __init__(self, rollout: int, fit: int) -> None:
        super().__init__()
        self.rollout, self.fit = int(rollout), int(fit)

    def _on_rollout_start(self) -> None:
        torch.set_num_threads(self.rollout)

    def _on_rollout_end(self) -> None:
        torch.set_num_threads(self.fit)

    def _on_training_end(self) -> None:
        torch.set_num_threads(self.rollout)

    def _on_step(self) -> bool:
        return True
