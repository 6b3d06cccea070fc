"""Episode-time feature: the agent's own clock, appended to the observation.

A blind policy for ``SoftHandPose-v0`` has to run a goal-dependent *sequence* (rolling loops,
then a translation); after a closed loop the joint frames repeat, so a memoryless policy needs
to know how far into the episode it is. The feature is the remaining fraction of the episode,
``1 - t / max_steps`` in [0, 1] (t = control steps taken since reset, 0 at reset), the value
and place of sb3-contrib's ``TimeFeatureWrapper``. It carries no information about the object.

* :class:`TimeFeature`: a Gymnasium wrapper of one env (an ``env_wrapper`` entry of a run;
  it records its keywords, so ``env.spec`` names it and ``gym.make(env.spec)`` rebuilds the
  wrapped env, as Minari's ``recover_environment`` does);
* :class:`VecTimeFeature`: the same feature for an SB3 ``VecEnv`` (the native vector env, which
  takes no single-env wrapper: :func:`agents.sb3.native_vec_env.make_sb3_vec_env` replaces
  :class:`TimeFeature` by it through :attr:`TimeFeature.vector_wrapper`).

Both append to a Box observation, or to the ``observation`` entry of a Dict observation (the
blind part the actor reads, :mod:`agents.sb3.policies`); the two give the same observations
(tested), so a model trained on either plays the other.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from agents.wrappers.obs_features import append_entries, space_with_entries

#: Largest episode length the feature accepts (control steps).
MAX_STEPS = 1_000_000


def _check_steps(max_steps: Any) -> int:
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) \
            or not 1 <= max_steps <= MAX_STEPS:
        raise ValueError(f"max_steps must be an int in [1, {MAX_STEPS}] (got {max_steps!r})")
    return int(max_steps)


def space_with_feature(space: gym.Space) -> gym.Space:
    """The observation space with the feature appended (1-D Box, or Dict with ``observation``)."""
    return space_with_entries(space, [0.0], [1.0], "the time feature")


def append_feature(obs: Any, t: np.ndarray | int, max_steps: int) -> Any:
    """``obs`` (one (D,) or a batch (N, D), or a Dict of them) with ``1 - t / max_steps``
    appended; ``t`` is an int or an (N,) int array of steps taken."""
    feat = (1.0 - np.minimum(t, max_steps) / max_steps).astype(np.float32)
    return append_entries(obs, feat[..., None])


class VecTimeFeature(VecEnvWrapper):
    """Append the remaining fraction of the episode to every env of an SB3 ``VecEnv``.

    Parameters
    ----------
    venv : VecEnv
        Box observations, or Dict observations with a Box ``observation`` entry.
    max_steps : int
        Episode length in control steps (the env's ``max_episode_steps``), in [1, 1e6].
    """

    def __init__(self, venv: VecEnv, max_steps: int):
        self.max_steps = _check_steps(max_steps)
        super().__init__(venv, observation_space=space_with_feature(venv.observation_space))
        self._t = np.zeros(venv.num_envs, dtype=np.int64)

    def reset(self) -> Any:
        self._t[:] = 0
        return append_feature(self.venv.reset(), self._t, self.max_steps)

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        self._t += 1
        for i in np.flatnonzero(dones):
            term = infos[i].get("terminal_observation")
            if term is not None:
                infos[i]["terminal_observation"] = append_feature(term, self._t[i],
                                                                  self.max_steps)
        self._t[dones] = 0
        return append_feature(obs, self._t, self.max_steps), rewards, dones, infos


class TimeFeature(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Append the remaining fraction of the episode to one env's observation (module doc).

    Parameters
    ----------
    env : gymnasium.Env
        Box observations, or Dict observations with a Box ``observation`` entry.
    max_steps : int
        Episode length in control steps (the env's ``max_episode_steps``), in [1, 1e6].
    """

    #: The equivalent wrapper of an SB3 VecEnv (used for the native vector env).
    vector_wrapper = VecTimeFeature

    def __init__(self, env: gym.Env, max_steps: int):
        gym.utils.RecordConstructorArgs.__init__(self, max_steps=max_steps)
        super().__init__(env)
        self.max_steps = _check_steps(max_steps)
        self.observation_space = space_with_feature(env.observation_space)
        self._t = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._t = 0
        return super().reset(seed=seed, options=options)

    def step(self, action: Any):
        self._t += 1
        return super().step(action)

    def observation(self, observation: Any) -> Any:
        return append_feature(observation, self._t, self.max_steps)
