"""Writing a run in RL Zoo's layout (:mod:`agents.runs.layout`; reading:
:mod:`agents.runs.loading`).

:func:`save_vecnormalize` writes observation statistics twice: ``.npz`` (plain arrays, what
:mod:`agents.runs.loading` reads) and ``.pkl`` (SB3's pickle, what ``rl_zoo3.enjoy`` reads).
:func:`write_run_config` writes ``<env id>/config.yml`` (the zoo's hyper-parameter
``OrderedDict`` plus our run record, with the sha256 of every model file of the run) and
``<env id>/args.yml``; ``<env id>/manifest.yml`` holds the digest of ``config.yml``'s
loading content (:func:`agents.runs.model_files.config_digest`) and is itself in the sha256
record, so an edited run config is refused when loaded.

Re-sealing a run after a change of the digest's definition (no retraining, no file but the
manifest and the sha256 record changes; refused if a recorded file no longer matches)::

    python -m agents.runs.writing RUN_DIR [RUN_DIR ...]
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from agents.runs.layout import ARGS_FILE, CONFIG_FILE, MANIFEST_FILE, RECORD_KEY
from agents.runs.model_files import config_digest, record_sha256, weights_sha256
from agents.runs.normalization import save_stats
from agents.runs.records import RunRecord
from agents.runs.zoo_dialect import zoo_yaml_dump


def save_vecnormalize(vecnormalize: Any, base: Path) -> None:
    """``base``.npz (plain arrays) and ``base``.pkl (SB3 pickle, for rl_zoo3) of a VecNormalize."""
    base.parent.mkdir(parents=True, exist_ok=True)
    save_stats(vecnormalize, base.with_suffix(".npz"))
    vecnormalize.save(str(base.with_suffix(".pkl")))


def model_files(run_dir: Path, env_id: str) -> list[Path]:
    """Files a model of the run is loaded from: zips, statistics, ``args.yml``, the manifest."""
    params = run_dir / env_id
    files = [*run_dir.glob("*.zip"), *run_dir.glob("*_vecnormalize*.npz"),
             *run_dir.glob("*_vecnormalize*.pkl"), *params.glob("vecnormalize.*")]
    for name in (ARGS_FILE, MANIFEST_FILE):
        if (params / name).is_file():
            files.append(params / name)
    return sorted(set(files))


def write_args(run_dir: Path, env_id: str, args: dict[str, Any]) -> None:
    """``<env id>/args.yml`` as the zoo writes it (keys sorted; ``env_kwargs`` None: the run's
    keywords are in ``config.yml``)."""
    params = run_dir / env_id
    params.mkdir(parents=True, exist_ok=True)
    zoo_yaml_dump({"env": env_id, "env_kwargs": None, **args}, params / ARGS_FILE)


def write_run_config(run_dir: Path, env_id: str, hyperparams: dict[str, Any],
                     record: RunRecord) -> Path:
    """``<env id>/config.yml``: ``hyperparams`` plus ``record`` under ``softhand`` with
    ``sha256`` of :func:`model_files` (written last, after every model file) and
    ``weights_sha256`` of each zip (:func:`~agents.runs.model_files.weights_sha256`: the
    network weights, unchanged by the zip's timestamps)."""
    return seal_config(run_dir, env_id, hyperparams, record.to_yaml())


def seal_config(run_dir: Path, env_id: str, hyperparams: dict[str, Any],
                saved: dict[str, Any], absent: dict[str, str] | None = None) -> Path:
    """Write ``<env id>/manifest.yml`` (the digest of ``hyperparams`` and the record
    ``saved``), then ``<env id>/config.yml``: ``hyperparams`` plus ``saved`` with ``sha256``
    of :func:`model_files` as they are now (plus the ``absent`` entries: recorded files not
    present, kept as recorded) and ``weights_sha256`` of each zip."""
    params = run_dir / env_id
    params.mkdir(parents=True, exist_ok=True)
    saved = {k: v for k, v in saved.items() if k not in ("sha256", "weights_sha256")}
    zoo_yaml_dump({"config_sha256": config_digest(hyperparams, saved)}, params / MANIFEST_FILE)
    files = model_files(run_dir, env_id)
    saved["sha256"] = {**(absent or {}), **record_sha256(run_dir, files)}
    saved["weights_sha256"] = {f.relative_to(run_dir).as_posix(): weights_sha256(f)
                               for f in files if f.suffix == ".zip"}
    path = params / CONFIG_FILE
    zoo_yaml_dump({**hyperparams, RECORD_KEY: saved}, path)
    return path


def read_run(run_dir: Path) -> tuple[str, dict[str, Any], dict[str, Any]]:
    """``(env id, hyper-parameters, record)`` of the run in ``run_dir`` (its one
    ``<env id>/config.yml``; ValueError if there is not exactly one)."""
    from agents.runs.zoo_dialect import zoo_yaml_load

    configs = [d for d in sorted(Path(run_dir).iterdir()) if (d / CONFIG_FILE).is_file()]
    if len(configs) != 1:
        raise ValueError(f"{run_dir}: expected one <env id>/{CONFIG_FILE}")
    config = zoo_yaml_load((configs[0] / CONFIG_FILE).read_text(), str(configs[0]))
    saved = config.pop(RECORD_KEY)
    if not isinstance(saved, dict):
        raise ValueError(f"{configs[0] / CONFIG_FILE}: no {RECORD_KEY} record")
    return configs[0].name, config, saved


def verified_files(run_dir: Path, env_id: str, saved: dict[str, Any]) -> dict[str, str]:
    """Check every file of the record's ``sha256`` present in ``run_dir`` against its
    checksum (ModelFileError on a mismatch; the manifest is rewritten, so not checked) and
    return the entries of the recorded files that are absent (e.g. a ``best_model.zip`` not
    shipped), which a re-sealed record keeps."""
    from agents.runs.model_files import check_sha256, check_sha_record

    sums = check_sha_record(saved.get("sha256"))
    absent = {}
    for rel, digest in sums.items():
        if not (Path(run_dir) / rel).is_file():
            absent[rel] = digest
        elif rel != f"{env_id}/{MANIFEST_FILE}":
            check_sha256(Path(run_dir), Path(run_dir) / rel, sums)
    return absent


def reseal(run_dir: Path) -> Path:
    """Rewrite the manifest and the sha256 record of the run in ``run_dir`` (an existing run
    whose every recorded file still has its recorded checksum; ValueError otherwise)."""
    env_id, config, saved = read_run(Path(run_dir))
    absent = verified_files(Path(run_dir), env_id, saved)
    return seal_config(Path(run_dir), env_id, config, saved, absent)


if __name__ == "__main__":
    import sys

    for arg in sys.argv[1:]:
        print(f"sealed {reseal(Path(arg))}")
