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


#: Entries always taken from the run config and the env, whatever the zip's ``data`` says.
CONFIG_ENTRIES = ("policy_class", "policy_kwargs", "observation_space", "action_space")


class ModelFileError(ValueError):
    """A model file that cannot be loaded safely (the message says why)."""


#: Bounds on an SB3 zip, checked before (declared sizes) and while (streamed sizes) any
#: member is decompressed: members, the ``data`` JSON, any one member, all members (bytes).
MAX_ZIP_MEMBERS = 64
MAX_DATA_BYTES = 8 << 20
MAX_MEMBER_BYTES = 256 << 20
MAX_ZIP_BYTES = 512 << 20
#: Largest zip file read (bytes, compressed).
MAX_ZIP_FILE_BYTES = 512 << 20
#: Deepest JSON nesting of ``data``.
MAX_JSON_DEPTH = 32


def _json_depth_ok(text: str, limit: int) -> bool:
    """Whether the brackets of a JSON text nest at most ``limit`` deep (strings skipped)."""
    depth, in_string, escaped = 0, False, False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > limit:
                return False
        elif ch in "]}":
            depth -= 1
    return True


def load_json_bounded(text: str | bytes, what: str, limit: int = MAX_JSON_DEPTH) -> Any:
    """``json.loads`` refused (ValueError naming ``what``) beyond ``limit`` levels of nesting
    or for integers of more than 30 digits, before it recurses or converts."""
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    if not _json_depth_ok(text, limit):
        raise ValueError(f"{what}: JSON nested deeper than {limit} levels")

    def bounded_int(digits: str) -> int:
        if len(digits.lstrip("-")) > 30:
            raise ValueError(f"{what}: integer longer than 30 digits")
        return int(digits)

    return json.loads(text, parse_int=bounded_int)


def check_zip_bounds(zip_path: str | Path) -> None:
    """ModelFileError unless the zip has at most :data:`MAX_ZIP_MEMBERS` members whose sizes,
    as declared in its directory AND as decompressed (streamed, stopped at the bound), stay
    within :data:`MAX_DATA_BYTES` (``data``), :data:`MAX_MEMBER_BYTES` (any member) and
    :data:`MAX_ZIP_BYTES` (all): a zip bomb is refused before it fills memory."""
    path = Path(zip_path)
    try:
        if path.stat().st_size > MAX_ZIP_FILE_BYTES:
            raise ModelFileError(f"larger than {MAX_ZIP_FILE_BYTES} bytes")
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            if len(infos) > MAX_ZIP_MEMBERS:
                raise ModelFileError(f"more than {MAX_ZIP_MEMBERS} members")
            total = 0
            for info in infos:
                bound = MAX_DATA_BYTES if info.filename == "data" else MAX_MEMBER_BYTES
                if info.file_size > bound or total + info.file_size > MAX_ZIP_BYTES:
                    raise ModelFileError(f"member {info.filename[:80]!r} declares "
                                         f"{info.file_size} bytes (at most {bound})")
                size = 0
                with archive.open(info) as fh:
                    while block := fh.read(1 << 20):
                        size += len(block)
                        if size > bound or total + size > MAX_ZIP_BYTES:
                            raise ModelFileError(f"member {info.filename[:80]!r} inflates "
                                                 f"beyond {bound} bytes")
                total += size
    except (OSError, zipfile.BadZipFile, EOFError, ValueError, NotImplementedError) as exc:
        if isinstance(exc, ModelFileError):
            raise
        raise ModelFileError(f"not an SB3 model file ({type(exc).__name__}: "
                             f"{str(exc)[:200]})") from None


def zip_data(zip_path: str | Path) -> dict[str, Any]:
    """The ``data`` JSON of an SB3 zip, parsed as JSON only (nothing unpickled), within the
    bounds of :func:`check_zip_bounds` and :data:`MAX_JSON_DEPTH`."""
    check_zip_bounds(zip_path)
    try:
        with zipfile.ZipFile(zip_path) as archive:
            data = load_json_bounded(archive.read("data"), "data")
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError, ValueError,
            RecursionError) as exc:
        raise ModelFileError(f"not an SB3 model file ({type(exc).__name__}: "
                             f"{str(exc)[:200]})") from None
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
    check_network_size(policy_kwargs.get("net_arch"), observation_space, action_space)
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


#: Most parameters of a policy's networks (actor and critics together), and widest layer.
MAX_PARAMETERS = 5_000_000
MAX_LAYER_WIDTH = 4096
MAX_LAYERS = 16


def _space_size(space: spaces.Space) -> int:
    import numpy as np

    if isinstance(space, spaces.Dict):
        return sum(_space_size(s) for s in space.spaces.values())
    return int(np.prod(space.shape or (1,)))


def check_network_size(net_arch: Any, observation_space: spaces.Space,
                       action_space: spaces.Space) -> int:
    """Parameters of the MLPs ``net_arch`` describes (a list of widths shared by the actor and
    the critic, or a mapping ``pi``/``vf``/``qf`` -> widths; None: SB3's 64-64), from the
    spaces' sizes, BEFORE torch builds them; ModelFileError beyond :data:`MAX_PARAMETERS`,
    :data:`MAX_LAYERS` layers or :data:`MAX_LAYER_WIDTH` units."""
    n_in, n_out = _space_size(observation_space), _space_size(action_space)
    if net_arch is None:
        net_arch = [64, 64]
    if isinstance(net_arch, list):
        arch = {"pi": net_arch, "vf": net_arch}
    elif isinstance(net_arch, dict):
        arch = dict(net_arch)
    else:
        raise ModelFileError("policy_kwargs.net_arch must be a list or a mapping")
    total = 0
    for name, widths in arch.items():
        if name not in ("pi", "vf", "qf") or not isinstance(widths, list):
            raise ModelFileError(f"policy_kwargs.net_arch: {str(name)[:40]!r} must be pi, vf "
                                 "or qf with a list of layer widths")
        if len(widths) > MAX_LAYERS or not all(
                isinstance(w, int) and not isinstance(w, bool) and 1 <= w <= MAX_LAYER_WIDTH
                for w in widths):
            raise ModelFileError(f"policy_kwargs.net_arch.{name}: at most {MAX_LAYERS} layers "
                                 f"of 1 .. {MAX_LAYER_WIDTH} units")
        head = 1 if name == "vf" else n_out
        sizes = [n_in + (n_out if name == "qf" else 0), *widths, head]
        total += sum((a + 1) * b for a, b in zip(sizes[:-1], sizes[1:], strict=True))
    if total > MAX_PARAMETERS:
        raise ModelFileError(f"policy_kwargs.net_arch has {total} parameters (at most "
                             f"{MAX_PARAMETERS})")
    return total


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
    # the network and the spaces always come from the run config and the env: a zip's own
    # (plain JSON) policy_kwargs or spaces are ignored, never merged
    custom = {k: v for k, v in custom.items() if k in pickled or k in CONFIG_ENTRIES}
    return algo_cls.load(str(zip_path), custom_objects=custom, device=device, **kwargs)


def sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


#: Largest ``policy.pth`` read from a zip by :func:`weights_sha256` (bytes).
MAX_POLICY_BYTES = 200_000_000


def weights_sha256(zip_path: str | Path) -> str:
    """Hex SHA-256 of the network weights in an SB3 zip, independent of the zip's
    timestamps and compression: the zip's ``policy.pth`` (read with
    ``torch.load(weights_only=True)``, no code run) as its parameters in sorted name order,
    each hashed as ``name``, dtype, shape and the little-endian bytes of the tensor.
    ModelFileError if the zip has no readable ``policy.pth``."""
    import io
    import zipfile

    import torch

    try:
        with zipfile.ZipFile(zip_path) as zf:
            info = zf.getinfo("policy.pth")
            if info.file_size > MAX_POLICY_BYTES:
                raise ModelFileError(f"{zip_path}: policy.pth is larger than "
                                     f"{MAX_POLICY_BYTES} bytes")
            data = zf.read(info)
        state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except (OSError, KeyError, zipfile.BadZipFile, RuntimeError, ValueError) as exc:
        raise ModelFileError(f"{zip_path}: no readable policy.pth ({exc})"[:300]) from None
    if not isinstance(state, dict):
        raise ModelFileError(f"{zip_path}: policy.pth is not a state dict")
    h = hashlib.sha256()
    for name in sorted(state):
        tensor = state[name].detach().cpu().contiguous()
        array = tensor.numpy()
        h.update(f"{name}|{array.dtype.str}|{tuple(array.shape)}|".encode())
        h.update(array.astype(array.dtype.newbyteorder("<"), copy=False).tobytes())
    return h.hexdigest()


def record_sha256(run_dir: Path, files: list[Path]) -> dict[str, str]:
    """``{path relative to run_dir (posix): sha256}`` of ``files``."""
    return {f.relative_to(run_dir).as_posix(): sha256(f) for f in sorted(files)}


def check_sha_record(record: Any) -> dict[str, str]:
    """The ``sha256`` entry of a run record, checked: a mapping of relative paths to 64-digit
    hex strings (ModelFileError otherwise)."""
    if not isinstance(record, dict) or len(record) > 10_000:
        raise ModelFileError(f"sha256 must be a mapping of file -> hex digest (got "
                             f"{type(record).__name__})")
    for key, value in record.items():
        if not (isinstance(key, str) and isinstance(value, str) and len(value) == 64
                and all(c in "0123456789abcdef" for c in value)):
            raise ModelFileError(f"sha256 entry {str(key)[:80]!r}: expected a 64-digit hex "
                                 "string")
    return record


def check_sha256(run_dir: Path, path: Path, record: dict[str, str]) -> None:
    """ModelFileError unless ``path`` is in ``record`` with its current checksum."""
    key = path.relative_to(run_dir).as_posix()
    if key not in check_sha_record(record):
        raise ModelFileError(f"{key} has no checksum in the run's config.yml")
    if sha256(path) != record[key]:
        raise ModelFileError(f"{key} does not match the checksum recorded in the run's "
                             "config.yml (the file was altered or swapped)")


#: Keys of the run record that loading reads (covered by :func:`config_digest`).
LOADING_RECORD_KEYS = ("algo", "env_id", "env_signature")


def config_digest(hyperparams: dict[str, Any], record: dict[str, Any]) -> str:
    """sha256 of what loading reads from ``config.yml``: the hyper-parameters (everything but
    the run record) and the record's :data:`LOADING_RECORD_KEYS`, as canonical JSON."""
    content = {"hyperparams": hyperparams,
               "record": {k: record.get(k) for k in LOADING_RECORD_KEYS}}
    text = json.dumps(content, sort_keys=True, default=repr, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()
