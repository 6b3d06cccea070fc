"""Saved runs: find a model, its normalisation statistics and run config; play it like a script.

The layout of a run, and the names of its files, are in :mod:`agents.runs.layout`.

:func:`resolve_model` finds the files of a model given as a run directory, a ``.zip`` in one,
or the id of a shipped model (``agents/models/<algo>/<env id>_1``, installed with the
package). :class:`ModelPolicy` loads it without running code from it (no pickle: see
:mod:`agents.runs.model_files`, :mod:`agents.runs.normalization`; ``env_wrapper`` allow-list:
:func:`agents.common.env_factory.wrapper_list`; checksums from ``config.yml``) and wraps it in the
scripted policies' ``predict`` signature, so one rollout loop evaluates both.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from agents.common.cli import UserError
from agents.common.env_factory import make_env, short_repr, wrapper_list
from agents.runs.hyperparams import ALGOS, algo_class, normalize_kwargs
from agents.runs.layout import (
    ARGS_FILE,
    CONFIG_FILE,
    MANIFEST_FILE,
    MODELS_DIR,
    RECORD_KEY,
    STATS_NPZ,
    stats_base,
)
from agents.runs.model_files import (
    ModelFileError,
    check_sha256,
    check_sha_record,
    config_digest,
    load_sb3,
)
from agents.runs.normalization import ObsNormalizer
from agents.runs.task_keywords import (
    AGENT_KEYS,
    MAX_EPISODE_STEPS,
    evaluation_kwargs,
    task_keys,
)
from agents.runs.zoo_dialect import zoo_yaml_load

TASK_KEY_SET = frozenset(task_keys())


@dataclass
class ModelRun:
    """The files and configuration of one saved model (see the module doc for the layout)."""

    zip_path: Path
    run_dir: Path
    env_id: str
    algo: str
    #: Hyper-parameters (``config.yml`` without our record).
    hyperparams: dict[str, Any]
    #: Our run record (``config.yml``'s ``softhand`` entry), empty for a run of rl_zoo3.train.
    record: dict[str, Any] = field(default_factory=dict)
    #: ``args.yml`` (empty if absent).
    args: dict[str, Any] = field(default_factory=dict)
    stats_npz: Path | None = None
    stats_pkl: Path | None = None

    @property
    def params_dir(self) -> Path:
        return self.run_dir / self.env_id

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """``gym.make`` keywords of the run (``args.yml`` overrides the config, as in RL Zoo)."""
        if self.args.get("env_kwargs") is not None:
            return dict(self.args["env_kwargs"])
        return dict(self.hyperparams.get("env_kwargs") or {})


def shipped_models() -> dict[str, Path]:
    """Name -> model zip of the shipped models: the env id names its default model (the run
    ``<env id>_1``, first in sorted order) and every run is also named by its directory
    (``SoftHandPose-v0_residual``)."""
    out: dict[str, Path] = {}
    for zip_path in sorted(MODELS_DIR.glob("*/*_*/*.zip")):
        env_id = zip_path.stem
        if zip_path.parent.name.startswith(env_id + "_"):
            out.setdefault(env_id, zip_path)
            out.setdefault(zip_path.parent.name, zip_path)
    return out


def _read_yaml(path: Path) -> dict[str, Any]:
    from softhand_env.physics.safe_yaml import read_bounded

    try:
        data = zoo_yaml_load(read_bounded(path), source=str(path))
    except (ValueError, TypeError) as exc:
        raise UserError(f"{path}: not readable as the zoo's YAML (plain values and OrderedDict "
                        f"only, no aliases): {' '.join(str(exc).split())[:300]}") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping")
    return data


def _stats_files(zip_path: Path, run_dir: Path, env_id: str) -> tuple[Path, Path]:
    base = stats_base(run_dir, env_id, zip_path.stem)
    return base.with_suffix(".npz"), base.with_suffix(".pkl")


def resolve_model(spec: str | Path) -> ModelRun:
    """The files of a saved model (:class:`ModelRun`).

    ``spec`` is a run directory (``<env id>.zip`` beside ``<env id>/config.yml``), a ``.zip``
    in one (final, ``best_model.zip`` or a checkpoint), or the env id of a shipped model.
    A bare name that is both a shipped model and a local path is refused (``./name`` is the
    local one).
    """
    p = Path(spec)
    if p.exists() and str(spec) in shipped_models():  # a local path shadows a shipped id
        raise UserError(f"{spec!r} names a shipped model and a local path; pass ./{spec} for "
                        "the local one or rename it")
    if not p.exists() and "/" not in str(spec) and not str(spec).endswith(".zip"):
        shipped = shipped_models()
        if str(spec) not in shipped:
            raise UserError(f"{spec!r} is neither a model path nor the id of a shipped model "
                            f"(shipped: {', '.join(shipped) or 'none'})")
        p = shipped[str(spec)]
    if p.is_dir():
        zips = [z for z in sorted(p.glob("*.zip")) if (p / z.stem / CONFIG_FILE).is_file()]
        if len(zips) != 1:
            raise UserError(f"{p} is not a run directory: expected <env id>.zip beside "
                            f"<env id>/{CONFIG_FILE} (the layout of rl_zoo3.train and "
                            "agents.train)")
        p = zips[0]
    if not p.is_file():
        raise UserError(f"model file {p} not found")
    run_dir = p.parent
    params = [d for d in sorted(run_dir.iterdir()) if (d / CONFIG_FILE).is_file()]
    if len(params) != 1:
        raise UserError(f"no <env id>/{CONFIG_FILE} beside {p} (one expected, found "
                        f"{len(params)})")
    env_id = params[0].name
    from softhand_env.envs import ENV_IDS

    if env_id not in ENV_IDS:  # before anything builds another package's env
        raise UserError(f"{p}: the run is of {short_repr(env_id)}, not a soft-hand environment "
                        f"({', '.join(ENV_IDS)})")
    hyperparams = _read_yaml(params[0] / CONFIG_FILE)
    record = hyperparams.pop(RECORD_KEY, None) or {}
    if not isinstance(record, dict):
        raise UserError(f"{params[0] / CONFIG_FILE}: {RECORD_KEY} must be a mapping")
    args_path = params[0] / ARGS_FILE
    args = _read_yaml(args_path) if args_path.is_file() else {}
    algo = args.get("algo") or record.get("algo") or run_dir.parent.name
    if not isinstance(algo, str) or algo not in ALGOS:
        raise UserError(f"{p}: unknown algo {short_repr(algo)} (from args.yml or the folder "
                        f"name; known: {', '.join(ALGOS)})")
    npz, pkl = _stats_files(p, run_dir, env_id)
    return ModelRun(zip_path=p, run_dir=run_dir, env_id=env_id, algo=algo,
                    hyperparams=hyperparams, record=record, args=args,
                    stats_npz=npz if npz.is_file() else None,
                    stats_pkl=pkl if pkl.is_file() else None)


class ModelPolicy:
    """A saved SB3 model (and its observation statistics) with the scripted ``predict`` API.

    Loading runs no code from the model's files: the zip's pickled entries are rebuilt from the
    run config and the env, weights are read with ``weights_only=True``, statistics from the
    ``.npz``, ``env_wrapper`` entries limited to an allow-list of classes with checked
    keywords, every file is checked against the sha256 recorded in ``config.yml`` and
    ``config.yml`` against the digest in its manifest (:mod:`agents.runs.layout`); every file
    is read within a size bound. The run's env keywords are checked (known keywords, no
    rendering, a bounded ``max_episode_steps``); :meth:`evaluation_kwargs` gives the
    keywords of the id's benchmark task (:mod:`agents.runs.task_keywords`).

    Parameters
    ----------
    spec : str or Path
        See :func:`resolve_model`.
    device : str
        Torch device.
    trust_model : bool
        Also accept what cannot be loaded without unpickling: ``:serialized:`` zip entries
        that cannot be rebuilt, and ``vecnormalize.pkl`` when there is no ``.npz`` (code in
        those files runs). Checksums, the wrapper allow-list and the env checks still apply.
    """

    def __init__(self, spec: str | Path, device: str = "cpu", trust_model: bool = False):
        run = resolve_model(spec)
        self.run = run
        #: The model zip.
        self.path = run.zip_path
        self.env_id = run.env_id
        self.algo = run.algo
        hp = run.hyperparams
        #: gym.make keywords of the run (including ``max_episode_steps`` if it set one).
        self.env_kwargs: dict[str, Any] = run.env_kwargs
        #: Wrappers of the run (``env_wrapper`` entry).
        self.env_wrapper = hp.get("env_wrapper")
        self.episode_steps: int | None = None
        wrapper_list(self.env_wrapper)  # the allow-list and its keywords, before any file check
        self._check_env_kwargs()
        norm = normalize_kwargs(hp.get("normalize"))
        stats = run.stats_npz if run.stats_npz is not None else run.stats_pkl
        self._check_files(stats if norm is not None else None)
        # the spaces depend on the agent's keywords only; the task's are the benchmark's
        probe = make_env(self.env_id, {k: v for k, v in self.env_kwargs.items()
                                       if k in AGENT_KEYS}, self.env_wrapper)
        obs_space, act_space = probe.observation_space, probe.action_space
        probe.close()
        extra = {"buffer_size": 1} if self.algo in ("sac", "td3", "tqc") else {}
        try:
            self.model = load_sb3(algo_class(self.algo), self.path, hp, obs_space, act_space,
                                  device=device, trust=trust_model, **extra)
        except (ModelFileError, UserError) as exc:
            raise UserError(f"cannot load model {self.path}: {exc}") from None
        except Exception as exc:  # zipfile, torch (weights_only refusals), shapes: "cannot load"
            raise UserError(f"cannot load model {self.path}: {type(exc).__name__}: {exc}") from None
        #: Frozen observation normalisation (callable), or None without normalisation.
        self.normalizer: Any = None
        if norm is not None:
            self.normalizer = self._load_stats(trust_model)
        self.recurrent = self.algo == "ppo_lstm"

    def _check_env_kwargs(self) -> None:
        """The run's env keywords as a mapping of known keywords, without viewer keywords, with
        a bounded ``max_episode_steps`` (UserError otherwise; the task keywords are compared
        with the benchmark's by :meth:`evaluation_kwargs`)."""
        source = f"{self.run.params_dir / CONFIG_FILE}"
        kwargs = self.run.hyperparams.get("env_kwargs")
        if self.run.args.get("env_kwargs") is not None:
            kwargs, source = self.run.args["env_kwargs"], f"{self.run.params_dir / ARGS_FILE}"
        if kwargs is not None and not isinstance(kwargs, dict):
            raise UserError(f"{source}: env_kwargs must be a mapping")
        evaluation_kwargs(self.env_id, {k: v for k, v in (kwargs or {}).items()
                                        if k not in TASK_KEY_SET}, source=source)
        steps = (kwargs or {}).get("max_episode_steps")
        if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int)
                                  or not 1 <= steps <= MAX_EPISODE_STEPS):
            raise UserError(f"{source}: max_episode_steps must be an int in [1, "
                            f"{MAX_EPISODE_STEPS}] (got {short_repr(steps)})")

    def evaluation_kwargs(self, overrides: dict[str, Any] | None = None,
                          env_id: str | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        """``gym.make`` keywords to evaluate the model on its id's benchmark task, and the
        task keywords ``overrides`` changed (see
        :func:`agents.runs.task_keywords.evaluation_kwargs`: a run config that sets a task
        keyword otherwise than the id is refused, UserError).

        ``env_id``: another registered id of the same task to play on instead (an
        off-signature evaluation, e.g. a ``-v0`` model on its ``-v1`` id): the run config is
        checked against its own id as above, then the model's agent keywords are played on
        ``env_id``'s task."""
        source = f"{self.run.params_dir / CONFIG_FILE}"
        kwargs, applied = evaluation_kwargs(self.env_id, self.env_kwargs, overrides,
                                            source=source)
        if env_id is None or env_id == self.env_id:
            return kwargs, applied
        from softhand_env.envs import ENV_IDS

        if ENV_IDS.get(env_id) != ENV_IDS[self.env_id]:
            raise UserError(f"the model was trained on {self.env_id} (task "
                            f"{ENV_IDS[self.env_id]}); {short_repr(env_id)} is not an id of "
                            "that task")
        agent = {k: v for k, v in self.env_kwargs.items() if k in AGENT_KEYS}
        return evaluation_kwargs(env_id, agent, overrides, source=source)

    def _check_files(self, stats: Path | None) -> None:
        run = self.run
        sums = run.record.get("sha256")
        if not sums:
            print(f"warning: {run.params_dir / CONFIG_FILE} records no sha256 of the model "
                  "files: a swapped file cannot be detected", file=sys.stderr)
            return
        files = [run.zip_path] + ([stats] if stats is not None else [])
        if (run.params_dir / ARGS_FILE).is_file():
            files.append(run.params_dir / ARGS_FILE)
        manifest = run.params_dir / MANIFEST_FILE
        try:
            check_sha_record(sums)
            for f in files:
                check_sha256(run.run_dir, f, sums)
            if not manifest.is_file():
                raise ModelFileError(f"{run.env_id}/{MANIFEST_FILE} is missing: the content "
                                     f"of {CONFIG_FILE} cannot be checked (re-seal a run you "
                                     "trust with python -m agents.runs.writing RUN_DIR)")
            check_sha256(run.run_dir, manifest, sums)
            sealed = _read_yaml(manifest).get("config_sha256")
            if sealed != config_digest(run.hyperparams, run.record):
                raise ModelFileError(f"{CONFIG_FILE} does not match the digest in "
                                     f"{MANIFEST_FILE} (the run config was edited)")
        except ModelFileError as exc:
            raise UserError(f"refusing {self.path}: {exc}") from None

    def _load_stats(self, trust_model: bool) -> Any:
        run = self.run
        space = self.model.observation_space
        obs_dim: int | dict[str, int] = (
            {k: int(np.prod(v.shape)) for k, v in space.spaces.items()}
            if hasattr(space, "spaces") else int(np.prod(space.shape)))
        if run.stats_npz is not None:
            try:
                return ObsNormalizer(run.stats_npz, obs_dim)
            except ValueError as exc:
                raise UserError(f"cannot load {exc}") from None
        if run.stats_pkl is None:
            raise UserError(f"{self.path}: the run normalises observations but has no "
                            f"{STATS_NPZ} for it")
        if not trust_model:
            raise UserError(f"{self.path}: the observation statistics are only in "
                            f"{run.stats_pkl.name} (a pickle, which can run code); pass "
                            "--trust-model to read it if you trust where it came from")
        import pickle

        try:
            with open(run.stats_pkl, "rb") as fh:
                vecnormalize = pickle.load(fh)  # noqa: S301 - only with --trust-model
            vecnormalize.training = False
            vecnormalize.norm_reward = False
        except Exception as exc:
            raise UserError(f"cannot load {run.stats_pkl}: {type(exc).__name__}: {exc}") from None
        return vecnormalize.normalize_obs

    def check_env(self, env: gym.Env, ignore: Sequence[str] = (),
                  allow_off_signature: bool = False) -> dict[str, str]:
        """Raise :class:`UserError` if the model does not fit ``env``; return the signature
        fields that differ and were let through.

        Two checks, both before the first step: the run's env signature (``env_signature`` of
        the run record in its ``config.yml``, written by :mod:`agents.train`: env id, package
        version, task, observation layout, action mapping, control period, sensor model; see
        :mod:`softhand_env.envs.signature`) against the signature of ``env``'s base
        environment, then the model's observation/action shapes against ``env``'s (wrappers
        included). ``ignore`` names signature fields not to hold against the model (e.g.
        ``version``); ``allow_off_signature`` lets every differing field through (an
        off-signature evaluation, e.g. a ``-v0`` model on its ``-v1`` id); the shapes must
        always match. A run without a signature (trained before signatures existed) only
        gets the shape check and a warning on stderr.

        Returns
        -------
        dict
            Field -> description with both values
            (:func:`~softhand_env.envs.signature.signature_differences`) of every differing
            field that was let through; empty: the model plays on its own signature.
        """
        from softhand_env.envs.signature import signature_differences

        saved = self.run.record.get("env_signature")
        tolerated: dict[str, str] = {}
        if saved is None:
            print(f"warning: {self.path} has no env_signature in its {CONFIG_FILE}: only the "
                  "observation and action shapes are checked", file=sys.stderr)
        else:
            if not isinstance(saved, dict):
                raise UserError(f"{self.path}: env_signature in its {CONFIG_FILE} must be a "
                                "mapping")
            found = signature_differences(saved, env)
            tolerated = {k: v for k, v in found.items()
                         if allow_off_signature or k in ignore}
            refused = [v for k, v in found.items() if k not in tolerated]
            if refused:
                text = ("trained model does not fit this environment; differing fields: "
                        + "; ".join(refused))
                raise UserError(f"{self.path}: {text[:500]} (retrain, or pass "
                                "--allow-off-signature to play it anyway, labelled not the "
                                "benchmark)")
        for name in ("observation_space", "action_space"):
            want, got = getattr(self.model, name).shape, getattr(env, name).shape
            if want != got:
                raise UserError(f"{self.path}: the model's {name} has shape {want}, the env's "
                                f"{got}")
        return tolerated

    def normalize(self, obs: Any) -> Any:
        """Observation as the model saw it in training (VecNormalize, statistics frozen)."""
        if self.normalizer is None:
            return obs
        return self.normalizer(obs)

    def predict(
        self,
        observation: Any,
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
