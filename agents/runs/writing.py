"""Writing a run in RL Zoo's layout (:mod:`agents.runs.layout`; reading:
:mod:`agents.runs.loading`).

:func:`save_vecnormalize` writes observation statistics twice: ``.npz`` (plain arrays, what
:mod:`agents.runs.loading` reads) and ``.pkl`` (SB3's pickle, what ``rl_zoo3.enjoy`` reads).
:func:`write_run_config` writes ``<env id>/config.yml`` (the zoo's hyper-parameter
``OrderedDict`` plus our run record, with the sha256 of every model file of the run) and
``<env id>/args.yml``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from agents.runs.layout import ARGS_FILE, CONFIG_FILE, RECORD_KEY
from agents.runs.model_files import record_sha256
from agents.runs.normalization import save_stats
from agents.runs.records import RunRecord
from agents.runs.zoo_dialect import zoo_yaml_dump


def save_vecnormalize(vecnormalize: Any, base: Path) -> None:
    """``base``.npz (plain arrays) and ``base``.pkl (SB3 pickle, for rl_zoo3) of a VecNormalize."""
    base.parent.mkdir(parents=True, exist_ok=True)
    save_stats(vecnormalize, base.with_suffix(".npz"))
    vecnormalize.save(str(base.with_suffix(".pkl")))


def model_files(run_dir: Path, env_id: str) -> list[Path]:
    """Files a model of the run is loaded from: zips, statistics, ``args.yml``."""
    params = run_dir / env_id
    files = [*run_dir.glob("*.zip"), *run_dir.glob("*_vecnormalize*.npz"),
             *run_dir.glob("*_vecnormalize*.pkl"), *params.glob("vecnormalize.*")]
    if (params / ARGS_FILE).is_file():
        files.append(params / ARGS_FILE)
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
    ``sha256`` of :func:`model_files` (written last, after every model file)."""
    params = run_dir / env_id
    params.mkdir(parents=True, exist_ok=True)
    saved = {**record.to_yaml(), "sha256": record_sha256(run_dir, model_files(run_dir, env_id))}
    path = params / CONFIG_FILE
    zoo_yaml_dump({**hyperparams, RECORD_KEY: saved}, path)
    return path
