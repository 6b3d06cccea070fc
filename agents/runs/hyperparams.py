"""Hyper-parameter files (RL Zoo's dialect, keyed by env id) and algorithm keywords.

:func:`load_hyperparams` reads ``agents/configs/<algo>.yml`` (installed with the
package) or the ``--conf-file`` given: a mapping keyed by env id, YAML anchors and merge keys
allowed, read with the bounds of :func:`softhand_env.physics.safe_yaml.load_bounded` (at most
1 MB, read before parsing; nesting and the alias-expanded size bounded). The files are
written in RL Zoo's dialect, so ``python -m rl_zoo3.train --gym-packages softhand_env
--conf-file <file>`` reads them unchanged: ``policy_kwargs`` as a ``"dict(...)"`` string
(read here without ``eval``, :mod:`agents.runs.zoo_dialect`), ``lin_<v>`` linear schedules.
:func:`algo_kwargs` turns an entry into algorithm keywords.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from agents.common.cli import UserError
from agents.runs.zoo_dialect import normalize_from, policy_kwargs_from
from softhand_env.physics.safe_yaml import load_bounded, read_bounded

#: Directory of the hyper-parameter files (``<algo>.yml``), installed with the package.
CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"

#: Algorithm name -> (module, class). Imported lazily (torch is slow to import).
ALGOS: dict[str, tuple[str, str]] = {
    "ppo": ("stable_baselines3", "PPO"),
    "sac": ("stable_baselines3", "SAC"),
    "td3": ("stable_baselines3", "TD3"),
    "tqc": ("sb3_contrib", "TQC"),
    "ppo_lstm": ("sb3_contrib", "RecurrentPPO"),
}

#: Keys of a hyper-parameter entry that train.py consumes (everything else goes to the algorithm).
#: ``vec_env`` (dummy | subproc | native) is ours: RL Zoo does not know it and takes the
#: vectorisation from its ``--vec-env`` flag, so the shipped zoo-dialect entries leave it out.
SPECIAL_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "env_wrapper",
                "vec_env")
#: Documented ranges of numeric algorithm keys (checked before the algorithm allocates its
#: buffers): key -> (low, high, integer?).
NUMERIC_RANGES: dict[str, tuple[float, float, bool]] = {
    "n_steps": (1, 1_000_000, True), "batch_size": (1, 10_000_000, True),
    "n_epochs": (1, 10_000, True), "buffer_size": (1, 10_000_000, True),
    "learning_starts": (0, 10**9, True), "gradient_steps": (-1, 10_000, True),
    "gamma": (0.0, 1.0, False), "gae_lambda": (0.0, 1.0, False), "tau": (0.0, 1.0, False),
    "vf_coef": (0.0, 1e3, False), "max_grad_norm": (0.0, 1e6, False),
    "learning_rate": (0.0, 10.0, False), "clip_range": (0.0, 10.0, False),
    "ent_coef": (0.0, 1e3, False),
    "n_envs": (1, 4096, True),
}
#: Keys whose value may be a ``lin_<v>`` schedule (as in RL Zoo).
SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")
#: Keys every entry must have.
REQUIRED_KEYS = ("n_timesteps", "policy")


# ---------------------------------------------------------------------------- hyper-params
def config_path(algo: str, conf_file: str | None) -> Path:
    """The hyper-parameter file: ``conf_file`` or ``agents/configs/<algo>.yml``."""
    if conf_file is not None:
        return Path(conf_file)
    for ext in ("yml", "yaml"):
        path = CONFIG_DIR / f"{algo}.{ext}"
        if path.exists():
            return path
    return CONFIG_DIR / f"{algo}.yml"


def load_hyperparams(algo: str, env_id: str, conf_file: str | None = None) -> dict[str, Any]:
    """The entry of ``env_id`` in the hyper-parameter file, validated (:class:`UserError`: one
    bounded line, also for a file beyond the size, depth or alias-expansion bounds)."""
    if algo not in ALGOS:
        raise UserError(f"unknown algo {algo!r}; choose one of {', '.join(ALGOS)}")
    path = config_path(algo, conf_file)
    if not path.is_file():
        raise UserError(f"hyper-parameter file {path} not found")
    try:  # bounded: size before parsing, depth, integer length, aliases as expanded
        data = load_bounded(read_bounded(path), yaml.SafeLoader, str(path), aliases=True)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping keyed by env id")
    if env_id not in data:
        keys = ", ".join(k for k in data if not str(k).startswith("."))
        raise UserError(f"{path} has no entry for {env_id!r} (entries: {keys})")
    entry = data[env_id]
    if not isinstance(entry, dict):
        raise UserError(f"{path}: entry {env_id!r} must be a mapping")
    missing = [k for k in REQUIRED_KEYS if k not in entry]
    if missing:
        raise UserError(f"{path}: entry {env_id!r} lacks required key(s) {', '.join(missing)}")
    hp = dict(entry)
    hp.setdefault("n_envs", 1)
    check_numeric("n_envs", hp["n_envs"])
    hp.setdefault("normalize", False)
    hp.setdefault("env_kwargs", {})
    if not isinstance(hp["env_kwargs"], dict):
        raise UserError(f"{path}: env_kwargs of {env_id!r} must be a mapping")
    return hp


def _schedule(key: str, value: Any) -> Any:
    """``lin_<v>`` -> a linear schedule from v (start) to 0 (end), as RL Zoo's ``lin_`` values
    (SB3's ``LinearSchedule``; rl_zoo3 itself is not imported in-process: importing it replaces
    gymnasium's ``TimeLimit`` for every env of the process)."""
    if isinstance(value, str):
        from stable_baselines3.common.utils import LinearSchedule

        kind, _, initial = value.partition("_")
        try:
            start = float(initial)
            if kind != "lin" or not math.isfinite(start):
                raise ValueError
        except ValueError:
            raise UserError(f"{key}: bad value {value!r} (a number or lin_<number>)") from None
        return LinearSchedule(start, 0.0, 1.0)
    return value


def check_numeric(key: str, value: Any) -> None:
    """:class:`UserError` if a numeric key of :data:`NUMERIC_RANGES` is out of its range, not
    finite or of the wrong type (strings such as ``lin_<v>`` or ``auto`` pass through)."""
    if key not in NUMERIC_RANGES or isinstance(value, str):
        return
    low, high, integer = NUMERIC_RANGES[key]
    ok_type = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type or not (math.isfinite(value)
                                                        and low <= value <= high):
        kind = "an int" if integer else "a number"
        raise UserError(f"{key} must be {kind} in [{low:g}, {high:g}] (got {value!r})")


def algo_class(algo: str) -> type:
    """The SB3 algorithm class of ``algo``."""
    import importlib

    module, name = ALGOS[algo]
    return getattr(importlib.import_module(module), name)


def algo_kwargs(algo: str, hp: dict[str, Any]) -> dict[str, Any]:
    """Algorithm constructor keywords from a hyper-parameter entry (validated)."""
    import inspect

    cls = algo_class(algo)
    allowed = set(inspect.signature(cls).parameters) - {"self", "env", "policy"}
    kwargs: dict[str, Any] = {}
    for key, value in hp.items():
        if key in SPECIAL_KEYS:
            continue
        if key not in allowed:
            raise UserError(f"{cls.__name__} has no hyper-parameter {key!r}")
        check_numeric(key, value)
        if key == "policy_kwargs":
            try:
                value = policy_kwargs_from(value)
            except (TypeError, ValueError) as exc:
                raise UserError(f"policy_kwargs: {exc}") from None
        elif key == "train_freq" and isinstance(value, list):
            value = tuple(value)
        elif key in SCHEDULE_KEYS:
            value = _schedule(key, value)
        kwargs[key] = value
    return kwargs


def normalize_kwargs(value: Any) -> dict[str, Any] | None:
    """VecNormalize keywords from ``normalize`` (false, true or a mapping), None if off."""
    try:
        return normalize_from(value)
    except (TypeError, ValueError) as exc:
        raise UserError(str(exc)) from None


def versions() -> dict[str, str]:
    """Versions of the packages a run depends on."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for pkg in ("softhand-env", "stable-baselines3", "sb3-contrib", "torch", "gymnasium", "numpy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            if pkg == "softhand-env":
                import softhand_env

                out[pkg] = softhand_env.__version__
    return out

