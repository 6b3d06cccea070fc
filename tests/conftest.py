"""Shared fixtures: environments that are closed after the test, and one rollout helper.

``make_env(env_id, **kwargs)`` is ``gym.make`` whose environments are closed at the end of the
test. ``rollout(env, seed, actions=..., policy=..., on_end=...)`` runs one environment and
records every transition as a :class:`Transition` (the reset first, with reward 0).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import softhand_env  # noqa: F401  (registers the environments)


@dataclass
class Transition:
    """One recorded ``reset`` (first) or ``step`` of a rollout.

    ``state`` is the physics state (20,) after it and ``params`` the hand parameters then.
    """

    obs: np.ndarray
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]
    state: np.ndarray
    params: Any


def run_rollout(
    env: gym.Env,
    seed: int | None = 0,
    actions: Iterable[np.ndarray] | None = None,
    policy: Any = None,
    on_end: str = "stop",
) -> list[Transition]:
    """Reset ``env`` with ``seed`` and step it, recording every transition.

    Actions come from ``actions`` (until exhausted) or from ``policy.predict(obs, state,
    episode_start)`` (Stable-Baselines3 interface; until the episode ends). On an episode end,
    ``on_end="stop"`` returns and ``on_end="reset"`` resets (unseeded, not recorded) and goes
    on with the next action.
    """
    if (actions is None) == (policy is None):
        raise ValueError("give exactly one of actions and policy")
    if on_end not in ("stop", "reset"):
        raise ValueError(f"on_end must be 'stop' or 'reset' (got {on_end!r})")
    base: Any = env.unwrapped
    obs, info = env.reset(seed=seed)
    out = [Transition(obs, 0.0, False, False, info, base.physics.get_state(),
                      base.physics.params)]

    def policy_actions() -> Iterator[np.ndarray]:
        state, start = None, np.array([True])
        while True:
            action, state = policy.predict(out[-1].obs, state, start)
            start = np.array([False])
            yield action

    for action in policy_actions() if policy is not None else actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out.append(Transition(obs, float(reward), bool(terminated), bool(truncated), info,
                              base.physics.get_state(), base.physics.params))
        if terminated or truncated:
            if on_end == "stop":
                break
            env.reset()
    return out


@pytest.fixture
def rollout() -> Callable[..., list[Transition]]:
    """:func:`run_rollout`."""
    return run_rollout


@pytest.fixture
def make_env() -> Iterator[Callable[..., gym.Env]]:
    """``gym.make`` whose environments are closed when the test ends."""
    made: list[gym.Env] = []

    def make(env_id: str, **kwargs: Any) -> gym.Env:
        env = gym.make(env_id, **kwargs)
        made.append(env)
        return env

    yield make
    for env in made:
        env.close()
