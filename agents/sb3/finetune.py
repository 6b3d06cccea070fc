"""Fine-tuning a started actor with PPO or A2C: a critic warm-up and the exploration noise.

A student distilled by DAgger (``agents.distill``) carries a fitted actor but an untrained
value network (DAgger fits the actor's mean action only). Started from such a model
(``agents.train --trained-agent``), PPO's first updates follow advantages of a random critic
and undo much of the actor (a PoseRandom-v1 student fell from 93 % to 80 % on validation
within 128 k steps). Two settings of ``agents.train`` make the start safe:

* ``--critic-warmup N``: in the updates that follow rollouts ending before env step N the
  actor's parameters (its network, the action head and the log standard deviation) are
  frozen and only the critic is fitted, at ``--critic-warmup-lr`` (the actor cannot move, so
  a large step size is safe); from the rollout that ends at step N or later on both train at
  the entry's learning rate. :class:`CriticWarmup` switches at the end of each
  rollout, before the update that follows it.
* ``--log-std V``: the policy's state-independent log standard deviation (per action
  dimension) is set to V after the weights are loaded; a distilled student keeps the value of
  its construction, which may explore far more coarsely than a precise task tolerates.

Both are recorded in the run's ``config.yml`` (``finetune``).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import asdict, dataclass
from typing import Any

import torch
from stable_baselines3.common.callbacks import BaseCallback

from agents.common.cli import UserError, check_range

#: Range of ``--log-std`` (a standard deviation from 4.5e-5 to 7.4 action units).
LOG_STD_RANGE = (-10.0, 2.0)
#: Algorithms whose policies have an actor, a critic and a log standard deviation.
FINETUNE_ALGOS = ("a2c", "ppo")


@dataclass(frozen=True)
class FineTune:
    """Fine-tuning settings of ``agents.train`` (see the module doc).

    Attributes
    ----------
    critic_warmup : int
        Env steps with a frozen actor (0: none), 0 .. 1e10.
    critic_warmup_lr : float
        Step size of the critic during the warm-up, (0, 1].
    log_std : float or None
        Log standard deviation set at the start (None: the model's own), in
        :data:`LOG_STD_RANGE`.
    """

    critic_warmup: int = 0
    critic_warmup_lr: float = 1e-3
    log_std: float | None = None

    def __post_init__(self) -> None:
        """Range checks (UserError on a bad value)."""
        check_range("--critic-warmup", self.critic_warmup, 0, 10**10)
        lr = self.critic_warmup_lr
        if not (isinstance(lr, float) and math.isfinite(lr) and 0.0 < lr <= 1.0):
            raise UserError(f"--critic-warmup-lr must be in (0, 1] (got {lr!r})")
        low, high = LOG_STD_RANGE
        if self.log_std is not None and not (math.isfinite(self.log_std)
                                             and low <= self.log_std <= high):
            raise UserError(f"--log-std must be in [{low:g}, {high:g}] (got {self.log_std!r})")

    @property
    def active(self) -> bool:
        """Whether any setting departs from plain training."""
        return self.critic_warmup > 0 or self.log_std is not None

    def check_algo(self, algo: str) -> None:
        """UserError if the settings are active and ``algo`` is not PPO or A2C."""
        if self.active and algo not in FINETUNE_ALGOS:
            algos = " and ".join(FINETUNE_ALGOS)
            raise UserError(f"--critic-warmup and --log-std apply to {algos} (got --algo {algo})")

    def to_yaml(self) -> dict[str, Any] | None:
        """The record's ``finetune`` entry (None when inactive)."""
        return asdict(self) if self.active else None

    @classmethod
    def from_namespace(cls, ns: argparse.Namespace) -> FineTune:
        """The settings of a command line parsed with :func:`add_arguments`."""
        return cls(critic_warmup=ns.critic_warmup, critic_warmup_lr=ns.critic_warmup_lr,
                   log_std=ns.log_std)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--critic-warmup``, ``--critic-warmup-lr`` and ``--log-std`` to ``parser``."""
    parser.add_argument("--critic-warmup", type=int, default=0,
                        help="PPO/A2C: env steps at the start in which only the critic is fitted "
                             "(the actor frozen), e.g. for a distilled student whose value "
                             "network is untrained; 0 .. 1e10, default 0")
    parser.add_argument("--critic-warmup-lr", type=float, default=1e-3,
                        help="step size of the critic during --critic-warmup, (0, 1]")
    parser.add_argument("--log-std", type=float, default=None,
                        help="PPO/A2C: set the policy's log standard deviation to this at the "
                             f"start, in [{LOG_STD_RANGE[0]:g}, {LOG_STD_RANGE[1]:g}]")


def critic_parameters(policy: Any) -> list[torch.nn.Parameter]:
    """Parameters of an SB3 ActorCriticPolicy's critic: its value head, the value branch of
    its MLP extractor and, when not shared with the actor, its own features extractor."""
    parts = [policy.value_net, policy.mlp_extractor.value_net]
    if not getattr(policy, "share_features_extractor", True):
        parts.append(policy.vf_features_extractor)
    return [p for part in parts for p in part.parameters()]


def actor_parameters(policy: Any) -> list[torch.nn.Parameter]:
    """Every other parameter of the policy (actor network, action head, log std, shared
    features extractor)."""
    critic = {id(p) for p in critic_parameters(policy)}
    return [p for p in policy.parameters() if id(p) not in critic]


def set_log_std(model: Any, value: float) -> None:
    """Set the log standard deviation of ``model``'s Gaussian policy to ``value`` (every
    action dimension); UserError for a policy without one (e.g. gSDE, discrete actions)."""
    log_std = getattr(model.policy, "log_std", None)
    if not isinstance(log_std, torch.nn.Parameter) or getattr(model, "use_sde", False):
        raise UserError("--log-std needs a Gaussian policy with a state-independent log std")
    with torch.no_grad():
        log_std.fill_(float(value))


class CriticWarmup(BaseCallback):
    """SB3 callback: each update after a rollout that ends before env step ``steps`` fits the
    critic alone (the actor's parameters have ``requires_grad`` False and no gradient, so the
    optimiser leaves them) with the constant step size ``lr``; after that the algorithm's own
    learning-rate schedule and every parameter again. Switched at the end of each rollout
    (before its update).

    Parameters
    ----------
    steps : int
        Env steps (all envs together) of the warm-up, >= 0.
    lr : float
        Step size of the warm-up updates, > 0.
    """

    def __init__(self, steps: int, lr: float) -> None:
        super().__init__()
        self.steps, self.lr = int(steps), float(lr)
        self._schedule: Any = None

    def _on_training_start(self) -> None:
        self._schedule = self.model.lr_schedule

    def _on_rollout_end(self) -> None:
        frozen = self.model.num_timesteps < self.steps
        for p in actor_parameters(self.model.policy):
            p.requires_grad_(not frozen)
            if frozen:
                p.grad = None
        lr = self.lr
        self.model.lr_schedule = (lambda _: lr) if frozen else self._schedule

    def _on_training_end(self) -> None:
        for p in actor_parameters(self.model.policy):
            p.requires_grad_(True)
        self.model.lr_schedule = self._schedule

    def _on_step(self) -> bool:
        return True
