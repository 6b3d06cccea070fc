"""Stable-Baselines3 ``VecEnv`` over the native Gymnasium vector env (:class:`NativeVecEnv`).

SB3 trains through its own ``VecEnv`` API; :class:`~softhand_env.envs.vector.SoftHandVectorEnv`
is a Gymnasium ``VectorEnv`` that advances N hands in one batched kernel call. This adapter
translates between the two conventions without copying any transition logic:

* **Autoreset.** The Gymnasium env (``NextStep`` or ``Disabled`` mode) reports the terminal
  step; the adapter then resets the finished environments at once through
  ``reset(options={"reset_mask": done})`` and returns the reset observation, with the
  terminal one in ``infos[i]["terminal_observation"]`` and
  ``infos[i]["TimeLimit.truncated"] = truncated and not terminated``, exactly as SB3's
  ``DummyVecEnv`` does with one ``gym.make`` env per slot. Reset infos go to
  :attr:`reset_infos`.
* **Infos.** The batched info dict (arrays with ``_key`` masks) becomes one dict per env.
* **Seeding.** ``seed(s)`` then ``reset()`` seeds env i with ``s + i`` (SB3's rule, and
  ``reset(seed=[...])`` of the vector env), so the same seeds and actions give the same
  transitions as ``DummyVecEnv`` (``tests/agents/test_native_vec_env.py``).
* **Episode statistics.** As under SB3's ``Monitor``, the info of an episode's last step
  carries ``"episode": {"r": return, "l": length, "t": seconds since creation}``. The adapter
  does this itself rather than under ``VecMonitor``, so that a training env
  ``VecNormalize(NativeVecEnv)`` has the wrapper depth of an evaluation env
  ``VecNormalize(DummyVecEnv)`` (``sync_envs_normalization`` walks both chains in step).
* **Attributes.** The N hands live in one object: :meth:`get_attr` returns the vector env's
  attribute once per requested index, :meth:`set_attr` and :meth:`env_method` act on the
  vector env once and need all indices (a per-env setting does not exist there).

:func:`make_sb3_vec_env` builds either this adapter (``vec_env="native"``) or the
``DummyVecEnv``/``SubprocVecEnv`` of monitored single envs of
:func:`agents.common.env_factory.make_vec_env`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

#: vec_env choices of :func:`make_sb3_vec_env`.
SB3_VEC_ENVS = ("dummy", "subproc", "native")


def split_infos(infos: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """One info dict per environment from a batched Gymnasium vector info.

    Parameters
    ----------
    infos : dict
        Batched info: ``key -> array (N, ...)`` with a bool mask ``_key`` (N,) saying which
        environments carry the key; nested dicts are split recursively.
    n : int
        Number of environments N.

    Returns
    -------
    list of N dicts. Entries of shape () become Python scalars (as the single env reports
    them), others are copied arrays.
    """
    keys = [key for key in infos if not key.startswith("_")]
    masks = [infos.get(f"_{key}") for key in keys]
    if not any(isinstance(infos[key], dict) or (mask is not None and not mask.all())
               for key, mask in zip(keys, masks, strict=True)):
        # every key in every environment (a step's info): the rows of all keys at once
        if not keys:
            return [{} for _ in range(n)]
        columns = [_items(np.asarray(infos[key]), copy=True) for key in keys]
        return [dict(zip(keys, row, strict=True)) for row in zip(*columns, strict=True)]
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, mask in zip(keys, masks, strict=True):
        value = infos[key]
        rows = np.arange(n) if mask is None else np.flatnonzero(mask)
        if isinstance(value, dict):
            nested = split_infos(value, n)
            for i in rows.tolist():
                out[i][key] = nested[i]
            continue
        # only the rows that carry the key (e.g. the environments just reset)
        for i, item in zip(rows.tolist(), _items(np.asarray(value)[rows], copy=False),
                           strict=True):
            out[i][key] = item
    return out


def _items(value: np.ndarray, copy: bool) -> list[Any]:
    """The rows of ``value`` (N, ...) as a list: Python scalars for shape (N,), objects as
    they are, else rows of one private copy (``copy`` False: ``value`` is one already)."""
    if value.dtype == object:
        return list(value)
    if value.ndim == 1:
        return value.tolist()
    return list(value.copy() if copy else value)


def _row(obs: Any, i: int) -> Any:
    """Observation of environment i (an array row or a dict of rows), copied."""
    if isinstance(obs, dict):
        return {k: v[i].copy() for k, v in obs.items()}
    return obs[i].copy()


class NativeVecEnv(VecEnv):
    """SB3 ``VecEnv`` view of a Gymnasium vector env (see module doc).

    Parameters
    ----------
    venv : gymnasium.vector.VectorEnv
        The batched env (e.g. ``gym.make_vec(id, num_envs=N,
        vectorization_mode="vector_entry_point")``), autoreset mode ``NextStep`` or
        ``Disabled`` (both honour ``reset(options={"reset_mask": mask})``). Box or Dict
        observations.
    """

    def __init__(self, venv: gym.vector.VectorEnv):
        mode = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        if AutoresetMode(mode) == AutoresetMode.SAME_STEP:
            raise ValueError(
                "NativeVecEnv needs autoreset_mode NextStep or Disabled (got SameStep)"
            )
        self.venv: Any = venv  # reset(seed=list) and reset_mask are SoftHandVectorEnv's
        self._actions: np.ndarray | None = None
        self._t0 = time.time()
        self._returns = np.zeros(venv.num_envs)
        self._lengths = np.zeros(venv.num_envs, dtype=np.int64)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.metadata = {**venv.metadata, "render_modes": self.metadata["render_modes"]}

    # ------------------------------------------------------------------------- reset/step
    def reset(self) -> Any:
        """Reset every env with the pending :meth:`seed` / :meth:`set_options` values.

        Environments with the same options are reset together (``reset_mask``); the options
        are passed to the vector env (which must accept them).
        """
        n = self.num_envs
        groups: dict[str, list[int]] = {}
        for i, opts in enumerate(self._options):
            groups.setdefault(repr(sorted(opts.items())), []).append(i)
        obs = None
        infos: list[dict[str, Any]] = [{} for _ in range(n)]
        for members in groups.values():
            opts = dict(self._options[members[0]])
            if len(members) < n:
                mask = np.zeros(n, dtype=bool)
                mask[members] = True
                opts["reset_mask"] = mask
            o, info = self.venv.reset(seed=list(self._seeds), options=opts or None)
            obs = o
            split = split_infos(info, n)
            for i in members:
                infos[i] = split[i]
        self.reset_infos = infos
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        self._actions = None
        n = self.num_envs
        dones = np.logical_or(terminated, truncated)
        infos = split_infos(info, n)
        self._returns += rewards
        self._lengths += 1
        for i in range(n):
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        if dones.any():
            t = round(time.time() - self._t0, 6)
            ended = np.flatnonzero(dones).tolist()
            for i in ended:
                infos[i]["terminal_observation"] = _row(obs, i)
                infos[i]["episode"] = {"r": round(float(self._returns[i]), 6),
                                       "l": int(self._lengths[i]), "t": t}
            self._returns[dones] = 0.0
            self._lengths[dones] = 0
            new_obs, reset_info = self.venv.reset(options={"reset_mask": dones.copy()})
            reset_split = split_infos(reset_info, n)
            for i in ended:
                self.reset_infos[i] = reset_split[i]
            obs = new_obs
        return obs, np.asarray(rewards, dtype=np.float32), dones, infos

    # --------------------------------------------------------------------------- access
    def _all(self, indices: VecEnvIndices, what: str) -> list[int]:
        idx = list(self._get_indices(indices))
        if sorted(idx) != list(range(self.num_envs)):
            raise ValueError(
                f"{what} on the native vector env acts on all {self.num_envs} environments "
                f"at once (got indices {idx}); per-environment {what} is not supported"
            )
        return idx

    def _owner(self, attr_name: str) -> Any:
        """The outermost of the vector env's wrappers (or the env itself) that has the
        attribute (Gymnasium's vector wrappers do not forward attributes)."""
        env = self.venv
        while not hasattr(env, attr_name) and isinstance(env, gym.vector.VectorWrapper):
            env = env.env
        if not hasattr(env, attr_name):
            raise AttributeError(f"the vector env has no attribute {attr_name!r}")
        return env

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector env's attribute ``attr_name`` (shared), once per requested index."""
        value = getattr(self._owner(attr_name), attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set ``attr_name`` on the vector env (shared by all environments; all indices)."""
        self._all(indices, "set_attr")
        setattr(self._owner(attr_name), attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call ``method_name`` of the vector env once; its result repeated per index.

        ``indices`` must select every environment, except for methods that are pure
        functions of their arguments (``compute_reward``), which SB3's HER calls on env 0.
        """
        if method_name != "compute_reward":
            idx = self._all(indices, "env_method")
        else:
            idx = list(self._get_indices(indices))
        result = getattr(self._owner(method_name), method_name)(*method_args, **method_kwargs)
        return [result for _ in idx]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """True for SB3's ``Monitor`` (the adapter reports its episode statistics), else False
        (there are no per-env Gymnasium wrappers)."""
        from stable_baselines3.common.monitor import Monitor

        wrapped = wrapper_class is Monitor
        return [wrapped for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        frames = self.venv.render()
        if frames is None:
            return [None] * self.num_envs
        return [np.asarray(frame) for frame in frames]

    def close(self) -> None:
        self.venv.close()


def make_sb3_vec_env(
    env_id: str,
    n_envs: int,
    seed: int | None,
    env_kwargs: dict[str, Any] | None = None,
    vec_env: str = "dummy",
    env_wrapper: Any = None,
) -> VecEnv:
    """SB3 ``VecEnv`` of ``n_envs`` copies of ``env_id``, monitored (``info["episode"]``).

    Parameters
    ----------
    env_id : str
        Registered id.
    n_envs : int
        Number of environments (>= 1).
    seed : int or None
        Env i is seeded ``seed + i`` at the first reset (None: entropy).
    env_kwargs : dict, optional
        ``gym.make`` keywords (``max_episode_steps`` included).
    vec_env : str
        ``"dummy"`` / ``"subproc"`` (single envs, :func:`agents.common.env_factory.make_vec_env`) or
        ``"native"`` (one :class:`~softhand_env.envs.vector.SoftHandVectorEnv` in
        :class:`NativeVecEnv`, which reports the episode statistics itself).
    env_wrapper : optional
        Single-env wrappers (``env_wrapper`` of the hyper-parameter YAML). The native vector
        env takes only wrappers with a ``vector_wrapper`` attribute (an SB3 ``VecEnvWrapper``
        taking the same keywords, e.g. :class:`agents.wrappers.time_feature.TimeFeature`),
        applied in the same order; any other raises ValueError.
    """
    if vec_env not in SB3_VEC_ENVS:
        raise ValueError(f"vec_env must be one of {SB3_VEC_ENVS} (got {vec_env!r})")
    if vec_env != "native":
        from agents.common.env_factory import make_vec_env

        return make_vec_env(env_id, n_envs, dict(env_kwargs or {}), seed, vec_env,
                            env_wrapper=env_wrapper)
    wrappers = vector_wrappers(env_wrapper)
    if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
        raise ValueError(f"n_envs must be an int >= 1 (got {n_envs!r})")
    venv = gym.make_vec(env_id, num_envs=int(n_envs), vectorization_mode="vector_entry_point",
                        **dict(env_kwargs or {}))
    sb3: VecEnv = NativeVecEnv(venv)
    if seed is not None:
        sb3.seed(seed)
    for cls, kw in wrappers:
        sb3 = cls(sb3, **kw)
    return sb3


def vector_wrappers(env_wrapper: Any) -> list[tuple[Any, dict[str, Any]]]:
    """The SB3 ``VecEnvWrapper`` classes (and keywords) equivalent to the single-env wrappers
    of an ``env_wrapper`` entry, in order: each class's ``vector_wrapper`` attribute. A wrapper
    without one raises ValueError (it cannot wrap the batched env)."""
    from agents.common.env_factory import wrapper_list

    out = []
    for cls, kw in wrapper_list(env_wrapper):
        vec_cls = getattr(cls, "vector_wrapper", None)
        if vec_cls is None:
            raise ValueError(
                f"vec_env: native takes only env_wrappers with a vector equivalent (single-env "
                f"wrappers cannot wrap the batched env); got {cls.__module__}.{cls.__name__}"
            )
        out.append((vec_cls, kw))
    return out
