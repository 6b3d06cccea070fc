"""Loading Stable-Baselines3 model files without unpickling anything, and file checksums.

An SB3 ``.zip`` holds the weights (``*.pth``, read by torch with ``weights_only=True``) and a
``data`` JSON whose non-JSON entries (policy class, spaces, schedules, buffers...) are
cloudpickled under a ``:serialized:`` key; SB3's ``load`` unpickles them, which runs any code
the file names. :func:`load_sb3` instead rebuilds every such entry from the run config and the
env (:func:`rebuilt_entries`) and hands them to SB3 as ``custom_objects``, so SB3 never
unpickles one; a zip with a ``:serialized:`` entry that cannot be rebuilt is refused unless
the caller trusts the file (``--trust-model``: SB3 then unpickles those entries).

:func:`sha256` / :func:`check_sha256` compare a run's files with the checksums recorded in its
``config.yml``, so a swapped or altered model file is refused.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path
from typing import Any

from gymnasium import spaces

#: ``:serialized:`` entries that describe training state only: rebuilt as None (SB3 recreates
#: the default buffers and statistics when it sets the model up).
RUNTIME_ENTRIES = ("_last_obs", "_last_original_obs", "_last_episode_starts", "ep_info_buffer",
                   "ep_success_buffer", "rollout_buffer_class", "replay_buffer_class",
                   "action_noise")
#: Every ``:serialized:`` entry :func:`rebuilt_entries` provides.
REBUILT_ENTRIES = ("policy_class", "policy_kwargs", "observation_space", "action_space",
                   "lr_schedule", "learning_rate", "clip_range", "clip_range_vf", "train_freq",
                   *RUNTIME_ENTRIES)


class ModelFileError(ValueError):
    """A model file that cannot be loaded safely (the message says why)."""


def zip_data(zip_path: str | Path) -> dict[str, Any]:
    """The ``data`` JSON of an SB3 zip, parsed as JSON only (nothing unpickled)."""
    try:
        with zipfile.ZipFile(zip_path) as archive:
            data = json.loads(archive.read("data"))
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError, ValueError) as exc:
        raise ModelFileError(f"not an SB3 model file ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict):
        raise ModelFileError("not an SB3 model file (data is not a JSON object)")
    return data


def serialized_entries(data: dict[str, Any]) -> list[str]:
    """Names of the ``:serialized:`` (pickled) entries of an SB3 zip's ``data`` JSON."""
    return [k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v]


def check_space_shapes(data: dict[str, Any], observation_space: spaces.Space,
                       action_space: spaces.Space) -> None:
    """ModelFileError if the shapes SB3 wrote beside the pickled spaces (plain JSON
    ``_shape``) differ from the env's."""
    for name, space in (("observation_space", observation_space), ("action_space", action_space)):
        entry = data.get(name)
        shape = entry.get("_shape") if isinstance(entry, dict) else None
        if isinstance(shape, list) and tuple(shape) != tuple(space.shape or ()):
            raise ModelFileError(f"the model's {name} has shape {tuple(shape)}, the env's "
                                 f"{tuple(space.shape or ())}")


def rebuilt_entries(algo_cls: Any, hyperparams: dict[str, Any],
                    observation_space: spaces.Space, action_space: spaces.Space
                    ) -> dict[str, Any]:
    """The ``:serialized:`` entries of a model, rebuilt from its run's hyper-parameters and the
    spaces of its env (:data:`REBUILT_ENTRIES`); ModelFileError if the config cannot give them.
    """
    from agents.runs.hyperparams import SCHEDULE_KEYS, _schedule
    from agents.runs.zoo_dialect import policy_kwargs_from

    policy = hyperparams.get("policy")
    aliases = getattr(algo_cls, "policy_aliases", {})
    if not isinstance(policy, str) or policy not in aliases:
        raise ModelFileError(f"policy {policy!r} is not one of {algo_cls.__name__}'s "
                             f"({', '.join(aliases)})")
    try:
        policy_kwargs = policy_kwargs_from(hyperparams.get("policy_kwargs") or {})
    except (TypeError, ValueError) as exc:
        raise ModelFileError(f"policy_kwargs: {exc}") from None
    out: dict[str, Any] = {
        "policy_class": aliases[policy],
        "policy_kwargs": policy_kwargs,
        "observation_space": observation_space,
        "action_space": action_space,
        **dict.fromkeys(RUNTIME_ENTRIES),
    }
    defaults = {"learning_rate": 3e-4, "clip_range": 0.2, "clip_range_vf": None}
    for key in SCHEDULE_KEYS:
        value = _schedule(key, hyperparams.get(key, defaults[key]))
        out[key] = value
    lr = out["learning_rate"]
    out["lr_schedule"] = lr if callable(lr) else (lambda _: float(lr))
    # off-policy algorithms: SB3 turns an int or (n, "step"|"episode") into its TrainFreq
    import inspect

    param = inspect.signature(algo_cls).parameters.get("train_freq")
    freq = hyperparams.get("train_freq", param.default if param is not None else 1)
    if isinstance(freq, list):
        freq = tuple(freq)
    if not (isinstance(freq, int) and not isinstance(freq, bool) or isinstance(freq, tuple)):
        raise ModelFileError(f"train_freq must be an int or [n, unit] (got {freq!r})")
    out["train_freq"] = freq
    return out


def load_sb3(algo_cls: Any, zip_path: str | Path, hyperparams: dict[str, Any],
             observation_space: spaces.Space, action_space: spaces.Space,
             device: str = "cpu", trust: bool = False, **kwargs: Any) -> Any:
    """``algo_cls.load(zip_path)`` with every pickled entry rebuilt (module doc).

    Raises ModelFileError naming the entries that cannot be rebuilt, unless ``trust`` (then SB3
    unpickles those, and only those). ``kwargs`` go to ``load`` (e.g. ``buffer_size=1``).
    """
    data = zip_data(zip_path)
    check_space_shapes(data, observation_space, action_space)
    pickled = serialized_entries(data)
    unknown = sorted(set(pickled) - set(REBUILT_ENTRIES))
    if unknown and not trust:
        raise ModelFileError(
            f"pickled entries {', '.join(unknown)} cannot be rebuilt from the run config; "
            "loading them would run code from the file (pass --trust-model only if you trust "
            "where it came from)")
    custom = rebuilt_entries(algo_cls, hyperparams, observation_space, action_space)
    custom = {k: v for k, v in custom.items() if k in pickled}
    return algo_cls.load(str(zip_path), custom_objects=custom, device=device, **kwargs)


def sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def record_sha256(run_dir: Path, files: list[Path]) -> dict[str, str]:
    """``{path relative to run_dir (posix): sha256}`` of ``files``."""
    return {f.relative_to(run_dir).as_posix(): sha256(f) for f in sorted(files)}


def check_sha256(run_dir: Path, path: Path, record: dict[str, str]) -> None:
    """ModelFileError unless ``path`` is in ``record`` with its current checksum."""
    key = path.relative_to(run_dir).as_posix()
    if key not in record:
        raise ModelFileError(f"{key} has no checksum in the run's config.yml")
    if sha256(path) != record[key]:
        raise ModelFileError(f"{key} does not match the checksum recorded in the run's "
                             "config.yml (the file was altered or swapped)")
