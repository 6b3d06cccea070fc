"""Saved runs: find a model, its normalisation statistics and run config; play it like a script.

:func:`resolve_model` finds a model zip, its VecNormalize statistics and the run's
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

import pickle
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from agents.cli import UserError
from agents.hyperparams import ALGOS, algo_class, normalize_kwargs

#: Files of a saved model directory.
MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
CONFIG_FILE = "config.yml"

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
        obs = self.normalize(np.asarray(observation, dtype=np.float32))
        if self.recurrent:
            return self.model.predict(obs, state, episode_start, deterministic)
        action, _ = self.model.predict(obs, deterministic=deterministic)
        return action, None
