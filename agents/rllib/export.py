"""An RLlib PPO RLModule exported as an ordinary SB3 PPO run (played by ``agents.evaluate``
without unpickling anything).

RLlib's default PPO module (``fcnet_hiddens`` H, separate actor and critic encoders,
``free_log_std``) and SB3's ``MlpPolicy`` with ``net_arch=dict(pi=H, vf=H)`` are the same
networks; :func:`sb3_policy_state` copies the weights one by one (:func:`key_map`):

=====================================================  ==================================
RLlib (learner's RLModule)                             SB3 ``policy.state_dict()``
=====================================================  ==================================
``encoder.actor_encoder.net.mlp.<2i>.{weight,bias}``    ``mlp_extractor.policy_net.<2i>``
``encoder.critic_encoder.net.mlp.<2i>.{weight,bias}``   ``mlp_extractor.value_net.<2i>``
``pi.net.mlp.0.{weight,bias}``                          ``action_net``
``vf.net.mlp.0.{weight,bias}``                          ``value_net``
``pi.log_std``                                          ``log_std``
=====================================================  ==================================

The deterministic action of both is the Gaussian's mean clipped to the action space. RLlib's
``MeanStdFilter`` normalises ``clip((obs - mean) / (std + 1e-6), -10, 10)`` (``std`` the
unbiased sample std); :func:`vecnormalize_moments` writes it as VecNormalize statistics with
``epsilon`` :data:`EPSILON` and ``var = (std + 1e-6)**2 - epsilon``, so that the run's
``sqrt(var + epsilon)`` is RLlib's divisor. :func:`write_run` writes the run in the layout of
:mod:`agents.runs.layout` (SB3 zip, ``vecnormalize.npz``/``.pkl``, ``args.yml``,
``config.yml`` with checksums and manifest) by building the SB3 model on the run's env, loading
the copied weights (strictly: every parameter, no other) and saving it with SB3.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.runs.records import RunConfig

#: Divisor offset of RLlib's filter (``ray.rllib.utils.numpy.SMALL_NUMBER``).
RLLIB_STD_OFFSET = 1e-6
#: ``epsilon`` of the exported statistics (the smallest the loader accepts).
EPSILON = 1e-12
#: RLModule entries that are not weights (RLlib's log-std clip constants).
NON_WEIGHTS = ("pi.log_std_clip_param_const", "vf.log_std_clip_param_const")


def key_map(n_hidden: int) -> dict[str, str]:
    """RLlib RLModule key -> SB3 policy key for ``n_hidden`` hidden layers (module doc)."""
    out = {"pi.log_std": "log_std"}
    for p in ("weight", "bias"):
        for i in range(0, 2 * n_hidden, 2):  # Linear, activation, Linear, ...
            out[f"encoder.actor_encoder.net.mlp.{i}.{p}"] = f"mlp_extractor.policy_net.{i}.{p}"
            out[f"encoder.critic_encoder.net.mlp.{i}.{p}"] = f"mlp_extractor.value_net.{i}.{p}"
        out[f"pi.net.mlp.0.{p}"] = f"action_net.{p}"
        out[f"vf.net.mlp.0.{p}"] = f"value_net.{p}"
    return out


def sb3_policy_state(weights: Mapping[str, Any], n_hidden: int) -> dict[str, Any]:
    """SB3 ``MlpPolicy`` state dict (torch float32 tensors) of an RLlib PPO module's
    ``weights`` (name -> array or tensor); ValueError unless the names are exactly those of
    :func:`key_map` (plus :data:`NON_WEIGHTS`)."""
    import torch

    mapping = key_map(n_hidden)
    names = set(weights) - set(NON_WEIGHTS)
    if names != set(mapping):
        raise ValueError("the RLModule is not RLlib's default PPO module of "
                         f"{n_hidden} hidden layers: missing {sorted(set(mapping) - names)}, "
                         f"unexpected {sorted(names - set(mapping))}")
    return {mapping[k]: torch.as_tensor(np.asarray(weights[k]), dtype=torch.float32).clone()
            for k in sorted(mapping)}


def vecnormalize_moments(filter_state: Mapping[Any, Any]) -> tuple[np.ndarray, np.ndarray, int]:
    """(mean, var, count) for VecNormalize (``epsilon`` :data:`EPSILON`) that normalise as the
    single-agent ``MeanStdFilter`` of ``filter_state`` (the connector's ``get_state()``)."""
    from ray.rllib.utils.filter import RunningStat

    (agent,) = filter_state.values()
    (stats,) = [RunningStat.from_state(s) for s in agent["running_stats"]]
    divisor = np.asarray(stats.std + RLLIB_STD_OFFSET, dtype=np.float64)  # float32 sum, as RLlib
    var = np.maximum(divisor**2 - EPSILON, 0.0)
    return np.asarray(stats.mean, dtype=np.float64), var, int(stats.n)


def write_run(run_dir: Path, config: RunConfig, weights: Mapping[str, Any],
              filter_state: Mapping[Any, Any] | None, num_timesteps: int) -> Path:
    """Write the exported run (module doc) into ``run_dir``; returns the model zip.

    ``config``: the run's hyper-parameters (an SB3 PPO entry whose ``normalize`` says how the
    statistics were made) and record (outcome set); ``weights``: the RLModule's;
    ``filter_state``: the observation filter's (None: no normalisation)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from agents.common.env_factory import make_env
    from agents.runs.hyperparams import algo_kwargs, normalize_kwargs
    from agents.runs.writing import save_vecnormalize, write_args, write_run_config

    hp, rec = config.hyperparams, config.record
    env_id = rec.env_id
    venv: Any = DummyVecEnv([lambda: make_env(env_id, hp["env_kwargs"], hp.get("env_wrapper"))])
    norm = normalize_kwargs(hp.get("normalize"))
    if (norm is None) != (filter_state is None):
        venv.close()
        raise ValueError("normalize and the observation filter disagree")
    if norm is not None and filter_state is not None:
        venv = VecNormalize(venv, training=False, **norm)
        venv.obs_rms.mean, venv.obs_rms.var, venv.obs_rms.count = vecnormalize_moments(
            filter_state)
    kwargs = algo_kwargs("ppo", hp)
    with warnings.catch_warnings():  # one env here: SB3 warns that batch_size > n_steps
        warnings.simplefilter("ignore", UserWarning)
        model = PPO(hp["policy"], venv, device="cpu", seed=rec.seed, verbose=0, **kwargs)
    n_hidden = len(model.policy.mlp_extractor.policy_net) // 2
    model.policy.load_state_dict(sb3_policy_state(weights, n_hidden), strict=True)
    model.num_timesteps = int(num_timesteps)
    params = run_dir / env_id
    params.mkdir(parents=True, exist_ok=True)
    zip_path = run_dir / f"{env_id}.zip"
    model.save(zip_path)
    if norm is not None:
        save_vecnormalize(venv, params / "vecnormalize")
    write_args(run_dir, env_id, {"algo": "ppo", "seed": rec.seed, "conf_file": rec.conf_file,
                                 "n_timesteps": int(hp["n_timesteps"]), "device": "cpu",
                                 "vec_env": rec.vec_env})
    write_run_config(run_dir, env_id, hp, rec)
    venv.close()
    return zip_path
