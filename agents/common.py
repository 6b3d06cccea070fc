"""Shared machinery of the training and evaluation CLIs (agents.train, agents.evaluate).

* Errors: :class:`UserError` is a wrong input (unknown env id, missing config key, bad keyword,
  unreadable model); :func:`run_cli` prints it as ONE line on stderr and exits with code 2.
* Hyper-parameters: :func:`load_hyperparams` reads the RL-Zoo-style YAML
  ``softhand_env/configs/agents/<algo>.yml`` (a mapping keyed by env id; YAML anchors allowed)
  and :func:`algo_kwargs` turns an entry into algorithm keywords (``lin_<v>`` schedules,
  ``activation_fn`` names).
* Environments: :func:`make_env` (``gym.make`` with clean errors), :func:`make_vec_env` (SB3
  ``DummyVecEnv``/``SubprocVecEnv`` with ``Monitor``), :class:`GoalSeeds` (a fixed, seeded goal
  set: episode k of a set starts with ``reset(seed=base + k)``).
* Success: :data:`SUCCESS_TOLERANCE` is issue 6's definition (|x err| < 1 mm, |theta err| < 1
  deg at the END of the episode); :func:`success_kwargs` gives the env keywords that set it,
  :func:`final_errors` the final errors of an episode from its last ``info``.
* Saved runs: :func:`resolve_model` finds a model zip, its VecNormalize statistics and the run's
  ``config.yml``; :class:`ModelPolicy` wraps a loaded model (with its normalisation) in the
  scripted policies' ``predict`` signature, so one rollout loop evaluates both.

Layout of a run directory written by :mod:`agents.train`::

    <log-folder>/<algo>/<env_id>_<k>/
        config.yml            config actually used (YAML entry + overrides, seed, versions,
                              env_signature: what the model depends on, checked on load)
        model.zip             final model          vecnormalize.pkl   its VecNormalize stats
        best/model.zip        best on the validation goals, best/vecnormalize.pkl
        checkpoints/          CheckpointCallback (model_<n>_steps.zip + vecnormalize)
        evaluations.npz       EvalCallback log;  tb/  TensorBoard event files
"""

from __future__ import annotations

import math
import pickle
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

#: Directory of the hyper-parameter files (``<algo>.yml``).
CONFIG_DIR = Path(__file__).resolve().parent.parent / "softhand_env" / "configs" / "agents"

#: Algorithm name -> (module, class). Imported lazily (torch is slow to import).
ALGOS: dict[str, tuple[str, str]] = {
    "ppo": ("stable_baselines3", "PPO"),
    "sac": ("stable_baselines3", "SAC"),
    "td3": ("stable_baselines3", "TD3"),
    "tqc": ("sb3_contrib", "TQC"),
    "ppo_lstm": ("sb3_contrib", "RecurrentPPO"),
}

#: Keys of a hyper-parameter entry that train.py consumes (everything else goes to the algorithm).
SPECIAL_KEYS = (
    "n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "env_wrapper", "vec_env",
)
#: Keys every entry must have.
REQUIRED_KEYS = ("n_timesteps", "policy")
#: ``vec_env`` values.
VEC_ENVS = ("dummy", "subproc")

#: Issue 6's success definition, fixed: per controlled coordinate, (env keyword, value).
SUCCESS_TOLERANCE: dict[str, tuple[str, float]] = {
    "x": ("x_tolerance_mm", 1.0),
    "theta": ("theta_tolerance_deg", 1.0),
}

#: Files of a saved model directory.
MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
CONFIG_FILE = "config.yml"


class UserError(Exception):
    """A wrong input; the CLIs print its message as one line and exit with code 2."""


def run_cli(main: Callable[[Sequence[str] | None], Any], argv: Sequence[str] | None = None) -> None:
    """Run a CLI ``main``; a :class:`UserError` becomes ``error: <msg>`` on stderr, exit 2."""
    try:
        main(argv)
    except UserError as exc:
        msg = " ".join(str(exc).split())  # one line
        print(f"error: {msg}", file=sys.stderr)
        sys.exit(2)


# ------------------------------------------------------------------------------ environments
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


def success_kwargs(env_id: str) -> dict[str, float]:
    """Env keywords that set issue 6's success tolerance (1 mm / 1 deg) for ``env_id``."""
    return dict(SUCCESS_TOLERANCE[t] for t in task_targets(env_id))


def wrapper_list(spec: Any) -> list[tuple[type, dict[str, Any]]]:
    """Wrapper classes and keywords from an ``env_wrapper`` entry (RL-Zoo syntax).

    ``spec`` is None, a dotted class path, or a list of dotted paths and one-key mappings
    ``{path: {keyword: value}}``, applied in order (innermost first).
    """
    import importlib

    if spec is None:
        return []
    items = spec if isinstance(spec, list) else [spec]
    out = []
    for item in items:
        if isinstance(item, dict) and len(item) == 1:
            path, kwargs = next(iter(item.items()))
            kwargs = dict(kwargs or {})
        elif isinstance(item, str):
            path, kwargs = item, {}
        else:
            raise UserError(f"env_wrapper items must be 'module.Class' or {{path: kwargs}} "
                            f"(got {item!r})")
        module, _, name = str(path).rpartition(".")
        try:
            cls = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError, ValueError):
            raise UserError(f"env_wrapper: cannot import {path!r}") from None
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
            env = Monitor(make_env(env_id, env_kwargs, env_wrapper))
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


# ---------------------------------------------------------------------------------- metrics
def final_errors(info: dict[str, Any], targets: Iterable[str]) -> dict[str, float]:
    """Final |x - x*| (mm) and |theta - theta*| (deg) from an episode's last ``info``.

    Only the controlled coordinates (``targets``, in goal order) are returned, as
    ``{"x_mm": ..., "theta_deg": ...}``.
    """
    targets = tuple(targets)
    if not targets:
        return {}
    pose, goal = np.asarray(info["object_pose"]), np.asarray(info["goal"])
    out = {}
    for name, g in zip(targets, goal, strict=True):
        if name == "x":
            out["x_mm"] = abs(float(pose[0]) - float(g)) * 1e3
        else:
            out["theta_deg"] = math.degrees(abs(float(pose[2]) - float(g)))
    return out


#: Controlled coordinate -> key of its final error.
ERROR_KEYS = {"x": "x_mm", "theta": "theta_deg"}


def summarize(
    targets: Sequence[str],
    successes: Sequence[bool],
    errors: Sequence[dict[str, float]],
    returns: Sequence[float] | None = None,
    lengths: Sequence[int] | None = None,
) -> dict[str, float]:
    """Success rate, median / mean / max final errors, mean return and length of episodes."""
    out: dict[str, float] = {"n_episodes": len(successes)}
    out["success_rate"] = float(np.mean(successes)) if len(successes) else math.nan
    for name in targets:
        key = ERROR_KEYS[name]
        e = np.array([err[key] for err in errors])
        out[f"median_{key}"] = float(np.median(e))
        out[f"mean_{key}"] = float(np.mean(e))
        out[f"max_{key}"] = float(np.max(e))
    if returns is not None:
        out["mean_return"] = float(np.mean(returns))
    if lengths is not None:
        out["mean_length"] = float(np.mean(lengths))
    return out


def error_score(summary: dict[str, float], targets: Sequence[str]) -> float:
    """Mean over targets of (median final error / success tolerance): lower is better."""
    vals = [summary[f"median_{ERROR_KEYS[t]}"] / SUCCESS_TOLERANCE[t][1] for t in targets]
    return float(np.mean(vals)) if vals else 0.0


# ---------------------------------------------------------------------------- hyper-params
def config_path(algo: str, conf_file: str | None) -> Path:
    """The hyper-parameter file: ``conf_file`` or ``configs/agents/<algo>.yml``."""
    if conf_file is not None:
        return Path(conf_file)
    for ext in ("yml", "yaml"):
        path = CONFIG_DIR / f"{algo}.{ext}"
        if path.exists():
            return path
    return CONFIG_DIR / f"{algo}.yml"


def load_hyperparams(algo: str, env_id: str, conf_file: str | None = None) -> dict[str, Any]:
    """The entry of ``env_id`` in the hyper-parameter file, validated (:class:`UserError`)."""
    if algo not in ALGOS:
        raise UserError(f"unknown algo {algo!r}; choose one of {', '.join(ALGOS)}")
    path = config_path(algo, conf_file)
    if not path.is_file():
        raise UserError(f"hyper-parameter file {path} not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise UserError(f"{path}: invalid YAML: {exc}") from None
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
    hp.setdefault("normalize", False)
    hp.setdefault("env_kwargs", {})
    hp.setdefault("vec_env", "dummy")
    if not isinstance(hp["env_kwargs"], dict):
        raise UserError(f"{path}: env_kwargs of {env_id!r} must be a mapping")
    return hp


def parse_kv(items: Sequence[str] | None, what: str = "--env-kwargs") -> dict[str, Any]:
    """``["k:v", ...]`` -> dict, each value parsed as YAML (``0.5``, ``true``, ``[6, 6]``)."""
    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, value = item.partition(":")
        if not sep or not key:
            raise UserError(f"{what} expects key:value items (got {item!r})")
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError:
            raise UserError(f"{what}: cannot parse the value of {item!r}") from None
    return out


def linear_schedule(initial: float) -> Callable[[float], float]:
    """``progress_remaining * initial`` (RL Zoo's ``lin_<value>``)."""

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _schedule(key: str, value: Any) -> Any:
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            return linear_schedule(float(value[4:]))
        except ValueError:
            raise UserError(f"{key}: bad schedule {value!r} (expected lin_<number>)") from None
    return value


def _policy_kwargs(value: dict[str, Any]) -> dict[str, Any]:
    import torch.nn as nn

    kwargs = dict(value)
    name = kwargs.get("activation_fn")
    if isinstance(name, str):
        table = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
        if name not in table:
            raise UserError(f"policy_kwargs.activation_fn must be one of {sorted(table)}")
        kwargs["activation_fn"] = table[name]
    return kwargs


def algo_class(algo: str) -> type:
    """The SB3 algorithm class of ``algo``."""
    import importlib

    module, name = ALGOS[algo]
    return getattr(importlib.import_module(module), name)


def algo_kwargs(algo: str, hp: dict[str, Any]) -> dict[str, Any]:
    """Algorithm constructor keywords from a hyper-parameter entry (validated)."""
    import inspect

    cls = algo_class(algo)
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "env", "policy"}
    kwargs: dict[str, Any] = {}
    for key, value in hp.items():
        if key in SPECIAL_KEYS:
            continue
        if key not in allowed:
            raise UserError(f"{cls.__name__} has no hyper-parameter {key!r}")
        if key == "policy_kwargs":
            if not isinstance(value, dict):
                raise UserError("policy_kwargs must be a mapping")
            value = _policy_kwargs(value)
        elif key == "train_freq" and isinstance(value, list):
            value = tuple(value)
        kwargs[key] = _schedule(key, value)
    return kwargs


def normalize_kwargs(value: Any) -> dict[str, Any] | None:
    """VecNormalize keywords from ``normalize`` (false, true or a mapping), None if off."""
    if value is False or value is None:
        return None
    if value is True:
        return {}
    if isinstance(value, dict):
        return dict(value)
    raise UserError(f"normalize must be true, false or a mapping (got {value!r})")


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


# ------------------------------------------------------------------------------ saved models
def resolve_model(path: str | Path) -> tuple[Path, Path | None, dict[str, Any]]:
    """Model zip, VecNormalize stats (or None) and run config of a saved model.

    ``path`` is a model directory (holding ``model.zip``), a run directory, or a ``.zip``
    file; the statistics are ``vecnormalize.pkl`` beside the zip, the config is
    ``config.yml`` beside it or one level up (``best/``, ``checkpoints/``).
    """
    p = Path(path)
    if p.is_dir():
        p = p / MODEL_FILE
    if not p.is_file():
        raise UserError(f"model file {p} not found")
    stats = p.parent / VECNORM_FILE
    if p.parent.name == "checkpoints":  # CheckpointCallback: model_<n>_steps.zip
        steps = p.stem.removeprefix("model_")
        stats = p.parent / f"model_vecnormalize_{steps}.pkl"
    for cfg_path in (p.parent / CONFIG_FILE, p.parent.parent / CONFIG_FILE):
        if cfg_path.is_file():
            break
    else:
        raise UserError(f"no {CONFIG_FILE} beside {p} or one level up")
    try:
        config = yaml.safe_load(cfg_path.read_text())
    except yaml.YAMLError as exc:
        raise UserError(f"{cfg_path}: invalid YAML: {exc}") from None
    if not isinstance(config, dict) or not {"algo", "env_id", "hyperparams"} <= set(config):
        raise UserError(f"{cfg_path}: not a run config (needs algo, env_id, hyperparams)")
    return p, (stats if stats.is_file() else None), config


class ModelPolicy:
    """A saved SB3 model (and its VecNormalize statistics) with the scripted ``predict`` API.

    Parameters
    ----------
    path : str or Path
        See :func:`resolve_model`.
    device : str
        Torch device.
    """

    def __init__(self, path: str | Path, device: str = "cpu"):
        zip_path, stats_path, config = resolve_model(path)
        #: The model zip.
        self.path = zip_path
        self.config = config
        self.env_id: str = config["env_id"]
        self.algo: str = config["algo"]
        if self.algo not in ALGOS:
            raise UserError(f"{zip_path}: unknown algo {self.algo!r} in its config")
        hp = config["hyperparams"]
        #: gym.make keywords of the run (including ``max_episode_steps`` if it set one).
        self.env_kwargs: dict[str, Any] = dict(hp.get("env_kwargs") or {})
        #: Wrappers of the run (``env_wrapper`` entry).
        self.env_wrapper = hp.get("env_wrapper")
        self.episode_steps: int | None = None
        try:
            self.model = algo_class(self.algo).load(str(zip_path), device=device)
        except Exception as exc:  # zipfile, pickle, torch, KeyError: all "cannot load"
            raise UserError(f"cannot load model {zip_path}: {type(exc).__name__}: {exc}") from None
        #: The run's VecNormalize (statistics frozen), or None without normalisation.
        self.vecnormalize = None
        if normalize_kwargs(hp.get("normalize")) is not None:
            if stats_path is None:
                raise UserError(
                    f"{zip_path}: the run normalises observations but has no {VECNORM_FILE} "
                    "beside the model"
                )
            try:
                with open(stats_path, "rb") as fh:
                    self.vecnormalize = pickle.load(fh)
                self.vecnormalize.training = False
                self.vecnormalize.norm_reward = False
            except Exception as exc:
                raise UserError(f"cannot load {stats_path}: {type(exc).__name__}: {exc}") from None
        self.recurrent = self.algo == "ppo_lstm"

    def check_env(self, env: gym.Env, ignore: Sequence[str] = ()) -> None:
        """Raise :class:`UserError` if the model does not fit ``env``.

        Two checks, both before the first step: the run's env signature (``env_signature`` in
        its ``config.yml``, written by :mod:`agents.train`: env id, package version, task,
        observation layout, action mapping, control period; see
        :mod:`softhand_env.envs.signature`) against the signature of ``env``'s base
        environment, then the model's observation/action shapes against ``env``'s (wrappers
        included). ``ignore`` names signature fields not to compare (e.g. ``version``). A run
        without a signature (trained before signatures existed) only gets the shape check and
        a warning on stderr.
        """
        from softhand_env.envs.signature import check_model_compatibility

        saved = self.config.get("env_signature")
        if saved is None:
            print(f"warning: {self.path} has no env_signature in its {CONFIG_FILE}: only the "
                  "observation and action shapes are checked", file=sys.stderr)
        else:
            try:
                check_model_compatibility(saved, env, ignore=tuple(ignore))
            except ValueError as exc:
                raise UserError(f"{self.path}: {exc} (retrain, or pass --ignore-signature "
                                "FIELD to run it anyway)") from None
        for name in ("observation_space", "action_space"):
            want, got = getattr(self.model, name).shape, getattr(env, name).shape
            if want != got:
                raise UserError(f"{self.path}: the model's {name} has shape {want}, the env's "
                                f"{got}")

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """Observation as the model saw it in training (VecNormalize, statistics frozen)."""
        if self.vecnormalize is None:
            return obs
        return self.vecnormalize.normalize_obs(obs)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3 prediction on the normalised observation (recurrent state passed through)."""
        if isinstance(observation, dict):  # Dict observations (goal_obs / privileged_obs)
            obs = self.normalize({k: np.asarray(v) for k, v in observation.items()})
        else:
            obs = self.normalize(np.asarray(observation, dtype=np.float32))
        if self.recurrent:
            return self.model.predict(obs, state, episode_start, deterministic)
        action, _ = self.model.predict(obs, deterministic=deterministic)
        return action, None
