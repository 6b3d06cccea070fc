"""Making a run's best validation model (or a checkpoint) its final model, in one checked step.

A run's final model is ``<env id>.zip`` with the statistics ``<env id>/vecnormalize.*``; what
``--model <run>`` and a shipped model id load. When the validation chose an earlier model
(``best_model.zip``, or a checkpoint ``rl_model_<n>_steps.zip``), :func:`promote` makes it the
final one:

* every file the run's ``config.yml`` records must still have its recorded checksum (the
  promoted model included), else nothing is written;
* the final model and its statistics are kept as ``final_model.zip`` and
  ``final_model_vecnormalize.*`` (loaded with their own statistics; nothing is lost);
* the chosen model and its statistics are copied over the final files;
* the record gains ``shipped_model``: ``{from: <file>, timesteps: <env steps>}`` and the
  checksums are rewritten (:func:`agents.runs.writing.seal_config`, as ``reseal`` does).

A run is promoted once (a second call is refused)::

    python -m agents.runs.promote RUN_DIR [--source best_model.zip]
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agents.common.cli import ArgumentParser, UserError, check_run_location, run_cli
from agents.runs.layout import (
    BEST_MODEL,
    CHECKPOINT,
    CONFIG_FILE,
    FINAL_MODEL,
    STATS_NPZ,
    STATS_PKL,
    stats_base,
)
from agents.runs.writing import read_run, seal_config, verified_files


def _source_timesteps(stem: str, saved: dict[str, Any]) -> int:
    """Env steps at which the model ``stem``.zip was saved (the checkpoint's name, or the
    record's ``best_validation``)."""
    match = CHECKPOINT.fullmatch(stem)
    if match:
        return int(match.group(1))
    best = saved.get("best_validation")
    if not isinstance(best, dict) or not isinstance(best.get("timesteps"), (int, float)):
        raise UserError("the run's record has no best_validation.timesteps for best_model.zip")
    return int(best["timesteps"])


def _copy(src: Path, dst: Path) -> None:
    """Copy ``src`` to ``dst`` through a temporary file, so ``dst`` is never half written."""
    tmp = dst.with_name(dst.name + ".tmp")
    shutil.copyfile(src, tmp)
    os.replace(tmp, dst)


def promote(run_dir: str | Path, source: str = f"{BEST_MODEL}.zip") -> Path:
    """Make ``run_dir``/``source`` (``best_model.zip`` or ``rl_model_<n>_steps.zip``) the
    run's final model, keeping the previous one as ``final_model.zip`` (see the module
    docstring). Returns the rewritten ``config.yml``. :class:`UserError` for a missing run
    directory or one inside the package's model folder, a source that is not one of those
    names or is absent, missing statistics, or a run promoted before;
    ``ModelFileError`` when a recorded file no longer has its checksum."""
    run_dir = Path(run_dir)
    stem = Path(source).stem
    if Path(source).name != source or Path(source).suffix != ".zip" or not (
            stem == BEST_MODEL or CHECKPOINT.fullmatch(stem)):
        raise UserError(f"--source must be {BEST_MODEL}.zip or rl_model_<n>_steps.zip in the "
                        f"run directory (got {source!r})")
    if not run_dir.is_dir():
        raise UserError(f"{run_dir}: no such run directory")
    check_run_location(run_dir, "the run directory")  # shipped models are never written to
    env_id, config, saved = read_run(run_dir)
    if "shipped_model" in saved:
        raise UserError(f"{run_dir}: already promoted (its record has shipped_model: "
                        f"{str(saved['shipped_model'])[:100]})")
    src_zip = run_dir / source
    if not src_zip.is_file():
        raise UserError(f"{src_zip}: no such model in the run")
    absent = verified_files(run_dir, env_id, saved)
    params = run_dir / env_id
    final_zip = run_dir / f"{env_id}.zip"
    kept_zip = run_dir / f"{FINAL_MODEL}.zip"
    if kept_zip.exists():
        raise UserError(f"{kept_zip} exists: the run was promoted before")
    pairs = [(final_zip, kept_zip, src_zip)]  # (final file, where it is kept, its replacement)
    src_stats = stats_base(run_dir, env_id, stem)
    own = src_stats.parent == run_dir  # else stats_base fell back to the final model's
    for suffix, name in ((".npz", STATS_NPZ), (".pkl", STATS_PKL)):
        final_stats, new_stats = params / name, src_stats.with_suffix(suffix)
        if final_stats.is_file() != (own and new_stats.is_file()):
            raise UserError(f"{run_dir}: {final_stats.name} and {new_stats.name} must both "
                            "exist or both be absent (the models' observation statistics)")
        if final_stats.is_file():
            pairs.append((final_stats, run_dir / f"{FINAL_MODEL}_vecnormalize{suffix}",
                          new_stats))
    for _, _, new in pairs:  # verified_files checked the recorded ones: all must be
        if new.relative_to(run_dir).as_posix() not in saved["sha256"]:
            raise UserError(f"{new} has no checksum in the run's {CONFIG_FILE}")
    saved["shipped_model"] = {"from": source, "timesteps": _source_timesteps(stem, saved)}
    for final, kept, new in pairs:
        _copy(final, kept)
        _copy(new, final)
    return seal_config(run_dir, env_id, config, saved, absent)


def main(argv: Sequence[str] | None = None) -> Path:
    """``python -m agents.runs.promote RUN_DIR [--source FILE]``."""
    parser = ArgumentParser(prog="python -m agents.runs.promote",
                            description="Make a run's best validation model (or a "
                            "checkpoint) its final model; the previous final model is kept "
                            "as final_model.zip.")
    parser.add_argument("run_dir", help=f"a run directory (<env id>.zip, <env id>/{CONFIG_FILE})")
    parser.add_argument("--source", default=f"{BEST_MODEL}.zip",
                        help="best_model.zip (default) or rl_model_<n>_steps.zip")
    ns = parser.parse_args(argv)
    path = promote(Path(ns.run_dir), ns.source)
    print(f"promoted {ns.source} in {ns.run_dir}; record {path}")
    return path


if __name__ == "__main__":
    run_cli(main)
