"""Action-history feature: the agent's own last commands, appended to the observation.

With a set-point latency (``setpoint_latency``, the ``Random`` ids) the set-points in the
observation are the *applied* ones, which lag the commands by the episode's latency; a policy
that also reads its last ``n`` actions can tell the latency from how the applied set-points
follow them. The feature is the last ``n`` actions (newest first, as given to ``step``,
clipped to the action space [-1, 1]; zeros after a reset), ``n * action_dim`` entries. It
carries no information about the object.

* :class:`ActionHistory`: a Gymnasium wrapper of one env (an ``env_wrapper`` entry of a run;
  its keywords are recorded in ``env.spec``, so ``gym.make(env.spec)`` rebuilds it);
* :class:`VecActionHistory`: the same for an SB3 ``VecEnv`` (the native vector env;
  :attr:`ActionHistory.vector_wrapper`).

Both append to a Box observation, or to the ``observation`` entry of a Dict observation, and
give the same observations (tested).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from agents.wrappers.obs_features import append_entries, space_with_entries

#: Largest number of actions kept.
MAX_ACTIONS = 100


def _check(n: Any, action_space: gym.Space) -> tuple[int, int]:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_ACTIONS:
        raise ValueError(f"n must be an int in [1, {MAX_ACTIONS}] (got {n!r})")
    if not isinstance(action_space, spaces.Box) or len(action_space.shape) != 1:
        raise ValueError(f"the action history needs a 1-D Box action space (got {action_space})")
    return int(n), int(action_space.shape[0])


def space_with_history(space: gym.Space, size: int) -> gym.Space:
    """The observation space with ``size`` entries in [-1, 1] appended (1-D Box, or Dict with
    ``observation``)."""
    return space_with_entries(space, np.full(size, -1.0), np.full(size, 1.0),
                              "the action history")


def append_history(obs: Any, history: np.ndarray) -> Any:
    """``obs`` (one (D,) or a batch (N, D), or a Dict of them) with ``history`` ((n, A) or
    (N, n, A), newest first) appended, flattened."""
    return append_entries(obs, history.reshape(*history.shape[:-2], -1).astype(np.float32))


def _push(history: np.ndarray, action: Any) -> None:
    """Shift ``history`` (..., n, A) one place and put the clipped ``action`` (..., A) first."""
    history[..., 1:, :] = history[..., :-1, :]
    history[..., 0, :] = np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0)


class VecActionHistory(VecEnvWrapper):
    """Append the last ``n`` actions to every env of an SB3 ``VecEnv`` (module doc).

    Parameters
    ----------
    venv : VecEnv
        Box observations, or Dict observations with a Box ``observation`` entry; 1-D Box
        actions.
    n : int
        Actions kept, in [1, 100].
    """

    def __init__(self, venv: VecEnv, n: int):
        self.n, dim = _check(n, venv.action_space)
        super().__init__(venv, observation_space=space_with_history(venv.observation_space,
                                                                    self.n * dim))
        self._history = np.zeros((venv.num_envs, self.n, dim), dtype=np.float32)

    def reset(self) -> Any:
        self._history[:] = 0.0
        return append_history(self.venv.reset(), self._history)

    def step_async(self, actions: np.ndarray) -> None:
        _push(self._history, actions)
        self.venv.step_async(actions)

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        for i in np.flatnonzero(dones):
            term = infos[i].get("terminal_observation")
            if term is not None:
                infos[i]["terminal_observation"] = append_history(term, self._history[i])
        self._history[dones] = 0.0
        return append_history(obs, self._history), rewards, dones, infos


class ActionHistory(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Append the last ``n`` actions to one env's observation (module doc).

    Parameters
    ----------
    env : gymnasium.Env
        Box observations, or Dict observations with a Box ``observation`` entry; 1-D Box
        actions.
    n : int
        Actions kept, in [1, 100].
    """

    #: The equivalent wrapper of an SB3 VecEnv (used for the native vector env).
    vector_wrapper = VecActionHistory

    def __init__(self, env: gym.Env, n: int):
        gym.utils.RecordConstructorArgs.__init__(self, n=n)
        super().__init__(env)
        self.n, dim = _check(n, env.action_space)
        self.observation_space = space_with_history(env.observation_space, self.n * dim)
        self._history = np.zeros((self.n, dim), dtype=np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._history[:] = 0.0
        return super().reset(seed=seed, options=options)

    def step(self, action: Any):
        _push(self._history, action)
        return super().step(action)

    def observation(self, observation: Any) -> Any:
        return append_history(observation, self._history)
