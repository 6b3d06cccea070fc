"""Environments of the CLIs: ``gym.make`` with clean errors, wrappers, seeded goal sets.

* :func:`make_env` (``gym.make`` with clean errors and the run's ``env_wrapper``),
  :func:`make_vec_env` (SB3 ``DummyVecEnv``/``SubprocVecEnv`` with ``Monitor``).
* :class:`GoalSeeds`: a fixed, seeded goal set: episode k of a set starts with
  ``reset(seed=base + k)``.
* :func:`task_targets`: the controlled coordinates of an env id.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
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


def short_repr(value: Any, limit: int = 120) -> str:
    """``repr(value)`` cut to about ``limit`` characters, without formatting more of a nested
    or aliased structure than it shows (for error messages about values read from files)."""
    import reprlib

    r = reprlib.Repr()
    r.maxlevel, r.maxdict, r.maxlist, r.maxtuple, r.maxset = 3, 8, 8, 8, 8
    r.maxstring, r.maxother, r.maxlong = limit, limit, 40
    text = r.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass(frozen=True)
class WrapperKeyword:
    """A keyword an allowed wrapper takes from a run config: ``kind`` ``"int"`` or
    ``"number"`` (finite), in ``[low, high]``."""

    kind: str
    low: float
    high: float

    def check(self, wrapper: str, name: str, value: Any) -> None:
        """:class:`UserError` naming the wrapper and keyword unless ``value`` fits."""
        import math

        is_int = isinstance(value, int) and not isinstance(value, bool)
        ok = (is_int if self.kind == "int" else
              (is_int or isinstance(value, float)) and math.isfinite(value))
        if not ok or not self.low <= value <= self.high:
            what = "an int" if self.kind == "int" else "a number"
            raise UserError(f"env_wrapper {wrapper}: {name} must be {what} in "
                            f"[{self.low:g}, {self.high:g}] (got {short_repr(value)})")


_TIME_FEATURE = {"max_steps": WrapperKeyword("int", 1, 1_000_000)}
_ACTION_HISTORY = {"n": WrapperKeyword("int", 1, 100)}
_RESIDUAL = {"delta_deg": WrapperKeyword("number", 1e-3, 30.0),
             "max_offset_deg": WrapperKeyword("number", 1e-3, 30.0)}
#: The wrapper classes an ``env_wrapper`` entry may name (dotted path -> the keywords it may
#: set, each checked before the class is built). Only observation / action transforms: nothing
#: that writes files, renders or runs a command. Published paths and the classes' homes.
ALLOWED_WRAPPERS: dict[str, dict[str, WrapperKeyword]] = {
    "agents.time_feature.TimeFeature": _TIME_FEATURE,
    "agents.wrappers.time_feature.TimeFeature": _TIME_FEATURE,
    "agents.action_history.ActionHistory": _ACTION_HISTORY,
    "agents.wrappers.action_history.ActionHistory": _ACTION_HISTORY,
    "agents.residual.ResidualWrapper": _RESIDUAL,
    "agents.wrappers.residual.ResidualWrapper": _RESIDUAL,
    "gymnasium.wrappers.FrameStackObservation": {"stack_size": WrapperKeyword("int", 1, 16)},
}
#: Most wrappers in one ``env_wrapper`` entry.
MAX_WRAPPERS = 8


def wrapper_list(spec: Any) -> list[tuple[type, dict[str, Any]]]:
    """Wrapper classes and keywords from an ``env_wrapper`` entry (RL Zoo syntax).

    ``spec`` is None, a dotted class path, or a list (at most :data:`MAX_WRAPPERS`) of dotted
    paths and one-key mappings ``{path: {keyword: value}}``, applied in order (innermost
    first). A path must be a key of :data:`ALLOWED_WRAPPERS` and its keywords the ones listed
    there, in range; this is checked before anything is imported, so a run config from
    elsewhere cannot make the loader import a module (or run its code), write files, or
    allocate without bound. Anything else raises :class:`UserError`.
    """
    import importlib

    if spec is None:
        return []
    items = spec if isinstance(spec, list) else [spec]
    if len(items) > MAX_WRAPPERS:
        raise UserError(f"env_wrapper: at most {MAX_WRAPPERS} wrappers (got {len(items)})")
    out = []
    for item in items:
        if isinstance(item, dict) and len(item) == 1:
            path, kwargs = next(iter(item.items()))
            if kwargs is not None and not isinstance(kwargs, dict):
                raise UserError(f"env_wrapper {short_repr(path)}: keywords must be a mapping")
            kwargs = dict(kwargs or {})
        elif isinstance(item, str):
            path, kwargs = item, {}
        else:
            raise UserError(f"env_wrapper items must be 'module.Class' or {{path: kwargs}} "
                            f"(got {short_repr(item)})")
        if not isinstance(path, str) or path not in ALLOWED_WRAPPERS:
            raise UserError(f"env_wrapper {short_repr(path)} refused: only these wrapper "
                            f"classes are allowed: {', '.join(ALLOWED_WRAPPERS)}")
        allowed = ALLOWED_WRAPPERS[path]
        for key, value in kwargs.items():
            if key not in allowed:
                raise UserError(f"env_wrapper {path}: keyword {short_repr(key)} is not "
                                f"allowed (allowed: {', '.join(allowed) or 'none'})")
            allowed[key].check(path, key, value)
        module, _, name = path.rpartition(".")
        cls = getattr(importlib.import_module(module), name)
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
        raise UserError(f"bad env kwargs for {env_id} {short_repr(kwargs)}: "
                        f"{str(exc)[:300]}") from None
    for cls, wkw in wrappers:
        try:
            env = cls(env, **wkw)
        except (TypeError, ValueError) as exc:
            env.close()
            raise UserError(f"env_wrapper {cls.__name__}: {str(exc)[:300]}") from None
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
    The worker processes of ``"subproc"`` ignore SIGINT and SIGTERM (a Ctrl-C reaches the
    terminal's whole process group): the main process decides how to stop
    (:mod:`agents.sb3.interrupts`) and closes them; they also end when its pipe closes.
    """
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if vec_env not in VEC_ENVS:
        raise UserError(f"vec_env must be one of {VEC_ENVS} (got {vec_env!r})")
    make_env(env_id, env_kwargs, env_wrapper).close()  # fail early, here, with a clean message

    def thunk(i: int) -> Callable[[], gym.Env]:
        def _init() -> gym.Env:
            if vec_env == "subproc":  # in the worker process
                import signal

                for signum in (signal.SIGINT, signal.SIGTERM):
                    signal.signal(signum, signal.SIG_IGN)
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

