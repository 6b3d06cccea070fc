"""Environment signatures: refuse to run a trained model on an environment it does not fit.

A policy trained on one observation layout silently does the wrong thing on another (a
``history_len=2`` model fed single frames, a ``proprio`` model fed tactile entries, a delta
policy driving absolute set-points). :func:`env_signature` describes what a model depends on;
``python -m agents.train`` stores it as ``env_signature`` in the run's ``config.yml`` and
``agents.evaluate`` (``ModelPolicy.check_env``) compares it with the env's
(:func:`signature_differences`) before the first step, exiting with one line naming every
differing field (with ``--allow-off-signature`` it plays and labels the result off-signature,
not the benchmark's); :func:`check_model_compatibility` is that check as one call (a
``ValueError``). Your own scripts can keep it in a JSON file next to the model
(:func:`save_env_signature`, :func:`signature_path`) or as the model's ``env_signature``
attribute (Stable-Baselines3 stores it in its zip).

Signature fields (JSON-friendly; :data:`SIGNATURE_FIELDS`):

=====================  ====================================================================
field                  meaning
=====================  ====================================================================
``env_id``             registered id (``SoftHandReorient-v0`` ...; the ``Random`` ids of the
                       randomisation ladder are distinct ids)
``version``            ``softhand_env.__version__``
``task``               ``none`` / ``reorient`` / ``translate`` / ``pose``
``obs_mode``           ``proprio`` or ``proprio_tactile``
``history_len``        observation frames
``observation_shape``  shape of one environment's observation, e.g. ``[9]``
``action_mode``        ``delta`` or ``absolute``
``normalize_action``   action in [-1, 1] (True) or set-points in rad (False)
``action_shape``       ``[2]``
``max_delta_deg``      set-point change of a full delta action (deg)
``joint_range_deg``    set-point range ``[low, high]`` (deg)
``control_dt``         control period (s)
``sensor_model``       ``ideal`` or ``realistic`` (:mod:`softhand_env.envs.sensors`): a
                       model trained on exact read-outs is refused on quantised, noisy ones
                       and the other way round; a signature saved before the field existed
                       reads ``ideal`` (:data:`LEGACY_VALUES`)
``onset_obs``          the grasp-onset entries follow the frames (a signature saved before
                       the field existed reads ``False``)
``setpoint_ramp_ms``   time over which a step's set-points move to the command (ms; a
                       signature saved before the field existed reads ``0.0``, a jump)
=====================  ====================================================================

The ``-v0`` and ``-v1`` ids are distinct ids (``env_id``), so a model trained on a ``-v0`` id
is refused on its ``-v1`` id (and on ``-v0`` with ``sensor_model="realistic"``).

Hand parameters are *not* part of the signature: evaluating a policy on another hand (or
under randomisation, the sensors' per-episode calibration ``rand_sensors`` and the noise
scale ``sensor_noise_scale`` included) is a
legitimate experiment, not a mismatch. Neither are the keywords that
only decide when an episode ends or how it is rewarded (``terminate_on_success``,
``terminate_on_slip``, the reward weights): they change no input or output of the model, so a
model trained before slip termination existed still loads, and evaluating it with slip
termination on measures whether its motions are physically possible.

Example::

    sig = env_signature(env)                       # at training time
    save_env_signature(sig, signature_path("runs/ppo/model.zip"))
    ...
    check_model_compatibility("runs/ppo/model.env.json", eval_env)   # ValueError on mismatch
"""

from __future__ import annotations

import json
import math
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

#: Fields of :func:`env_signature`, in order.
SIGNATURE_FIELDS = (
    "env_id",
    "version",
    "task",
    "obs_mode",
    "history_len",
    "observation_shape",
    "action_mode",
    "normalize_action",
    "action_shape",
    "max_delta_deg",
    "joint_range_deg",
    "control_dt",
    "sensor_model",
    "onset_obs",
    "setpoint_ramp_ms",
)

#: Values of fields added after signatures were first saved, as a signature without the field
#: means them (the model was trained when only that value existed).
LEGACY_VALUES: dict[str, Any] = {"sensor_model": "ideal", "onset_obs": False,
                                 "setpoint_ramp_ms": 0.0}

#: Relative tolerance for float fields (they round-trip through degrees/radians and JSON).
FLOAT_RTOL = 1e-9


def _config_and_id(env: Any) -> tuple[Any, str | None]:
    """The :class:`~softhand_env.envs.config.EnvConfig` of ``env`` and its spec id (or None).

    Accepts a (wrapped) :class:`~softhand_env.envs.SoftHandEnv`, the native
    :class:`~softhand_env.envs.SoftHandVectorEnv`, Gymnasium's Sync/Async vector envs and
    Stable-Baselines3 VecEnvs (through their ``get_attr``).
    """
    from softhand_env.envs.config import EnvConfig

    base = getattr(env, "unwrapped", env)
    cfg = getattr(base, "config", None)
    spec = getattr(env, "spec", None) or getattr(base, "spec", None)
    if not isinstance(cfg, EnvConfig) and hasattr(env, "get_attr"):
        try:
            cfg = env.get_attr("config")[0]
            if spec is None:
                spec = env.get_attr("spec")[0]
        except (AttributeError, IndexError):
            cfg = None
    if not isinstance(cfg, EnvConfig):
        raise ValueError(f"not a softhand-env environment: {env!r}")
    return cfg, (spec.id if spec is not None else None)


def _registered_id(env: Any, task: str) -> str:
    """Id of an environment constructed without ``gym.make``: among the ids of its task whose
    registered keywords (:func:`softhand_env.envs.registered_kwargs`) it all has, the one
    with the most keywords (e.g. the ``Random`` ``-v1`` id for
    :data:`~softhand_env.envs.RANDOM_KWARGS`, :data:`~softhand_env.envs.V1_KWARGS` and
    :data:`~softhand_env.envs.V1_RANDOM_KWARGS`); the task's ``-v0`` id if none fits."""
    from softhand_env.envs import ENV_IDS, registered_kwargs

    base = getattr(env, "unwrapped", env)
    options = getattr(base, "options", None)
    if options is None and hasattr(env, "get_attr"):
        options = env.get_attr("options")[0]
    ids = [i for i, t in ENV_IDS.items() if t == task]
    fitting = [i for i in ids if options is not None and all(
        getattr(options, k) == v for k, v in registered_kwargs(i).items())]
    return max(fitting, key=lambda i: len(registered_kwargs(i))) if fitting else ids[0]


def env_signature(env: Any) -> dict[str, Any]:
    """What a model trained on ``env`` depends on (see the module doc), as a JSON-able dict.

    Parameters
    ----------
    env
        A softhand environment: ``gym.make(...)`` (any wrappers), the native vector env,
        a Gymnasium vector env or an SB3 VecEnv of softhand environments.
    """
    import softhand_env
    cfg, env_id = _config_and_id(env)
    if env_id is None:  # constructed directly: the id registered for the task and keywords
        env_id = _registered_id(env, cfg.task.name)
    actions = cfg.actions
    return {
        "env_id": env_id,
        "version": softhand_env.__version__,
        "task": cfg.task.name,
        "obs_mode": cfg.layout.obs_mode,
        "history_len": cfg.layout.history_len,
        "observation_shape": [cfg.layout.size],
        "action_mode": actions.mode,
        "normalize_action": actions.normalize,
        "action_shape": [2],
        "max_delta_deg": math.degrees(actions.max_delta),
        "joint_range_deg": [math.degrees(actions.low), math.degrees(actions.high)],
        "control_dt": cfg.dt,
        "sensor_model": cfg.sensors.name,
        "onset_obs": cfg.layout.onset,
        "setpoint_ramp_ms": cfg.setpoint_ramp * cfg.params.dt * 1e3,
    }


def signature_path(model_path: str | os.PathLike) -> Path:
    """Conventional signature file next to a model: ``model.zip`` -> ``model.env.json``."""
    path = Path(model_path)
    return path.with_name(path.name.removesuffix(".zip") + ".env.json")


def save_env_signature(signature_or_env: Any, path: str | os.PathLike) -> Path:
    """Write a signature (or the signature of an env) to ``path`` as JSON; returns the path."""
    if isinstance(signature_or_env, dict):
        sig = signature_or_env
    else:
        sig = env_signature(signature_or_env)
    path = Path(path)
    path.write_text(json.dumps(sig, indent=2, sort_keys=False) + "\n")
    return path


def load_env_signature(path: str | os.PathLike) -> dict[str, Any]:
    """Read a signature written by :func:`save_env_signature` (``ValueError`` if unreadable)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"cannot read env signature {str(path)!r}: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: an env signature must be a JSON object")
    return data


def _same(a: Any, b: Any) -> bool:
    """Equality with JSON normalisation (tuples = lists, NumPy scalars = Python numbers) and a
    relative tolerance :data:`FLOAT_RTOL` for numbers; a bool only equals a bool."""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    a_bool, b_bool = isinstance(a, (bool, np.bool_)), isinstance(b, (bool, np.bool_))
    if a_bool or b_bool:
        return a_bool and b_bool and bool(a) == bool(b)
    numbers = (int, float, np.integer, np.floating)
    if isinstance(a, numbers) and isinstance(b, numbers):
        return math.isclose(float(a), float(b), rel_tol=FLOAT_RTOL, abs_tol=0.0)
    return a == b


def signature_differences(saved: dict[str, Any], env: Any,
                          ignore: tuple[str, ...] = ()) -> dict[str, str]:
    """The fields in which a saved signature and ``env``'s differ.

    Parameters
    ----------
    saved : dict
        A model's signature (:func:`env_signature` at training time); a field it lacks reads
        as in :data:`LEGACY_VALUES`.
    env
        Anything :func:`env_signature` takes.
    ignore : tuple of str
        Fields not to compare.

    Returns
    -------
    dict
        Field -> a description with both values, e.g. ``"env_id (model 'SoftHandPose-v0', env
        'SoftHandPose-v1')"``, in the env signature's field order (then fields only the model
        has); empty when the model fits.
    """
    return _differences({**LEGACY_VALUES, **saved}, env_signature(env), set(ignore))


def _differences(saved: dict[str, Any], current: dict[str, Any], ignore) -> dict[str, str]:
    out = {}
    for key in list(current) + [k for k in saved if k not in current]:
        if key in ignore:
            continue
        if key not in saved:
            out[key] = f"{key} (missing from the model's signature; env {current[key]!r})"
        elif key not in current:
            out[key] = f"{key} (model {saved[key]!r}; unknown to this version of the env)"
        elif not _same(saved[key], current[key]):
            out[key] = f"{key} (model {saved[key]!r}, env {current[key]!r})"
    return out


def check_model_compatibility(
    model_or_metadata: Any, env: Any, ignore: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Raise ``ValueError`` if a trained model does not fit ``env``; return the env signature.

    Parameters
    ----------
    model_or_metadata
        One of: a signature dict (:func:`env_signature`); a path to a signature JSON file
        (:func:`save_env_signature`); or a model object (e.g. a Stable-Baselines3 algorithm)
        with an ``env_signature`` dict attribute and/or ``observation_space`` /
        ``action_space``. Spaces present on the model are compared too (field names
        ``observation_space`` / ``action_space``); a model without a signature only gets the
        space check and a ``UserWarning``.
    env
        The environment the model is about to run on (anything :func:`env_signature` takes).
    ignore : tuple of str
        Signature fields not to compare (e.g. ``("version",)`` to run an old model on purpose).

    Raises
    ------
    ValueError
        Naming every differing field with both values, e.g.
        ``obs_mode (model 'proprio', env 'proprio_tactile')``.
    """
    current = env_signature(env)
    problems: list[str] = []
    saved: dict[str, Any] | None = None
    if isinstance(model_or_metadata, dict):
        saved = model_or_metadata
    elif isinstance(model_or_metadata, (str, os.PathLike)):
        saved = load_env_signature(model_or_metadata)
    else:
        saved = getattr(model_or_metadata, "env_signature", None)
        if saved is not None and not isinstance(saved, dict):
            raise ValueError(f"model.env_signature must be a dict (got {type(saved).__name__})")
        for name, key in (("observation_space", "observation_shape"),
                          ("action_space", "action_shape")):
            space = getattr(model_or_metadata, name, None)
            if space is not None and name not in ignore:
                shape = list(getattr(space, "shape", None) or ())
                if shape != current[key]:
                    problems.append(f"{name} (model shape {shape}, env shape {current[key]})")
        if saved is None:
            if not hasattr(model_or_metadata, "observation_space"):
                raise ValueError(
                    "model_or_metadata must be a signature dict, a signature file or a model "
                    f"with env_signature / observation_space (got {model_or_metadata!r})"
                )
            warnings.warn(
                "the model carries no env signature: only its spaces were checked",
                UserWarning,
                stacklevel=2,
            )
    if saved is not None:
        saved = {**LEGACY_VALUES, **saved}
        problems += list(_differences(saved, current, set(ignore)).values())
    if problems:
        raise ValueError(
            "trained model does not fit this environment; differing fields: "
            + "; ".join(problems)
        )
    return current


__all__ = [
    "LEGACY_VALUES",
    "SIGNATURE_FIELDS",
    "check_model_compatibility",
    "env_signature",
    "load_env_signature",
    "save_env_signature",
    "signature_differences",
    "signature_path",
]
