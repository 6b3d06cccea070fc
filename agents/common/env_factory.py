"""Environments of the CLIs: ``gym.make`` with clean errors, wrappers, seeded goal sets.

* :func:`make_env` (``gym.make`` with clean errors and the run's ``env_wrapper``),
  :func:`make_vec_env` (SB3 ``DummyVecEnv``/``SubprocVecEnv`` with ``Monitor``).
* :class:`GoalSeeds`: a fixed, seeded goal set: episode k of a set starts with
  ``reset(seed=base + k)``.
* :func:`task_targets`: the controlled coordinates of an env id.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym

from agents.common.cli import UserError

#: ``vec_env`` values.
VEC_ENVS = ("dummy", "subproc")


def register() -> None:
    """Register the soft-hand environments (``import softhand_env``)."""
    import softhand_env  # noqa: F401


def check_env_id(env_id: str) -> None:
    """Raise :class:`UserError` unless ``env_id`` is a registered Gymnasium id."""
    register()
    if env_id not in gym.registry:
        ours = sorted(k for k in gym.registry if k.startswith("SoftHand"))
        raise UserError(f"unknown env id {env_id!r}; registered soft-hand ids: {', '.join(ours)}")


def task_targets(env_id: str) -> tuple[str, ...]:
    """Controlled coordinates of a soft-hand env id: ``()``, ``("x",)``, ``("theta",)``, both."""
    from softhand_env.envs import ENV_IDS
    from softhand_env.envs.task_configs import TASK_TARGETS

    check_env_id(env_id)
    if env_id not in ENV_IDS:
        raise UserError(f"{env_id!r} is not a soft-hand environment ({', '.join(ENV_IDS)})")
    return TASK_TARGETS[ENV_IDS[env_id]]


#: Modules an ``env_wrapper`` entry may name a class from: the project's own packages and
#: Gymnasium's wrappers. Anything else is refused before it is imported.
WRAPPER_MODULES = ("agents", "softhand_env", "gymnasium.wrappers")


def wrapper_list(spec: Any) -> list[tuple[type, dict[str, Any]]]:
    """Wrapper classes and keywords from an ``env_wrapper`` entry (RL Zoo syntax).

    ``spec`` is None, a dotted class path, or a list of dotted paths and one-key mappings
    ``{path: {keyword: value}}``, applied in order (innermost first). A path must name a
    ``gymnasium.Wrapper`` subclass in :data:`WRAPPER_MODULES` (checked before any import, then
    on the imported object); anything else raises :class:`UserError`, so a run config from
    elsewhere cannot make the loader import or call arbitrary code.
    """
    import importlib

    if spec is None:
        return []
    items = spec if isinstance(spec, list) else [spec]
    out = []
    for item in items:
        if isinstance(item, dict) and len(item) == 1:
            path, kwargs = next(iter(item.items()))
            if kwargs is not None and not isinstance(kwargs, dict):
                raise UserError(f"env_wrapper {path!r}: keywords must be a mapping")
            kwargs = dict(kwargs or {})
        elif isinstance(item, str):
            path, kwargs = item, {}
        else:
            raise UserError(f"env_wrapper items must be 'module.Class' or {{path: kwargs}} "
                            f"(got {item!r})")
        module, _, name = str(path).rpartition(".")
        allowed = any(module == m or module.startswith(m + ".") for m in WRAPPER_MODULES)
        if not allowed or not name.isidentifier() or name.startswith("_"):
            raise UserError(f"env_wrapper {path!r} refused: only wrapper classes from "
                            f"{', '.join(WRAPPER_MODULES)} are allowed")
        try:
            cls = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError, ValueError):
            raise UserError(f"env_wrapper: cannot import {path!r}") from None
        if not (isinstance(cls, type) and issubclass(cls, gym.Wrapper)):
            raise UserError(f"env_wrapper {path!r} refused: not a gymnasium.Wrapper class")
        out.append((cls, kwargs))
    return out


def make_env(
    env_id: str,
    env_kwargs: dict[str, Any] | None = None,
    env_wrapper: Any = None,
    **extra: Any,
) -> gym.Env:
    """``gym.make(env_id, **env_kwargs, **extra)`` wrapped by ``env_wrapper`` (see
    :func:`wrapper_list`); bad keywords raise :class:`UserError`.

    ``env_kwargs`` may hold ``max_episode_steps`` (the ``TimeLimit``), as ``gym.make`` does.
    """
    check_env_id(env_id)
    kwargs = {**(env_kwargs or {}), **extra}
    wrappers = wrapper_list(env_wrapper)
    try:
        env = gym.make(env_id, **kwargs)
    except (TypeError, ValueError) as exc:
        raise UserError(f"bad env kwargs for {env_id} {kwargs}: {exc}") from None
    for cls, wkw in wrappers:
        try:
            env = cls(env, **wkw)
        except TypeError as exc:
            raise UserError(f"env_wrapper {cls.__name__}: {exc}") from None
    return env


class GoalSeeds(gym.Wrapper):
    """A fixed, seeded goal set: the k-th reset without a seed is ``reset(seed=seeds[k % n])``.

    :meth:`rewind` starts the set over (the evaluation callback calls it before every
    evaluation, so each evaluation sees the same goals).
    """

    def __init__(self, env: gym.Env, seeds: Sequence[int]):
        super().__init__(env)
        if not seeds:
            raise ValueError("GoalSeeds needs at least one seed")
        self.seeds = [int(s) for s in seeds]
        self._k = 0

    def rewind(self) -> None:
        """Next reset uses ``seeds[0]``."""
        self._k = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is None:
            seed = self.seeds[self._k % len(self.seeds)]
            self._k += 1
        return self.env.reset(seed=seed, options=options)


def goal_seeds(base: int, n: int) -> list[int]:
    """Seeds of a goal set: episode k starts with ``reset(seed=base + k)``."""
    return [int(base) + k for k in range(int(n))]


def make_vec_env(
    env_id: str,
    n_envs: int,
    env_kwargs: dict[str, Any],
    seed: int | None,
    vec_env: str = "dummy",
    seeds: Sequence[int] | None = None,
    env_wrapper: Any = None,
):
    """SB3 ``VecEnv`` of ``n_envs`` monitored copies of ``env_id``.

    With ``seeds`` (a goal set), copy i plays ``seeds[i::n_envs]`` through :class:`GoalSeeds`;
    else the copies are seeded ``seed + i`` at the first reset and continue their streams.
    """
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if vec_env not in VEC_ENVS:
        raise UserError(f"vec_env must be one of {VEC_ENVS} (got {vec_env!r})")
    make_env(env_id, env_kwargs, env_wrapper).close()  # fail early, here, with a clean message

    def thunk(i: int) -> Callable[[], gym.Env]:
        def _init() -> gym.Env:
            env: gym.Env = Monitor(make_env(env_id, env_kwargs, env_wrapper))
            if seeds is not None:
                env = GoalSeeds(env, list(seeds)[i::n_envs])
            elif seed is not None:
                env.action_space.seed(seed + i)
            return env

        return _init

    cls = DummyVecEnv if vec_env == "dummy" else SubprocVecEnv
    venv = cls([thunk(i) for i in range(n_envs)])
    if seeds is None and seed is not None:
        venv.seed(seed)
    return venv

