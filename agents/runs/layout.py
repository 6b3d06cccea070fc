"""The on-disk layout of a run and the names of its files (read by :mod:`agents.runs.loading`,
written by :mod:`agents.runs.writing`).

A run is laid out as RL Zoo lays out its runs (``rl_zoo3.train`` writes the same, and
``rl_zoo3.enjoy -f <log-folder>`` plays ours)::

    <log-folder>/<algo>/<env_id>_<k>/
        <env_id>.zip                  final model (SB3 zip)
        <env_id>/config.yml           hyper-parameters (the zoo's OrderedDict YAML); ours add a
                                      ``softhand`` entry: env signature, seed, validation
                                      results, versions, the sha256 of every model file and
                                      of each zip's weights (weights_sha256)
        <env_id>/args.yml             command-line arguments (the zoo's; env_kwargs)
        <env_id>/manifest.yml         sha256 of config.yml's loading content (hyper-parameters,
                                      algo, env signature); config.yml records its sha256
        <env_id>/vecnormalize.npz     observation statistics as plain arrays (read here)
        <env_id>/vecnormalize.pkl     the same as SB3 pickles it (read by rl_zoo3 only)
        best_model.zip                best on the validation goals (+ best_model_vecnormalize.*)
        final_model.zip               the final model before the best one replaced it
                                      (agents.runs.promote; + final_model_vecnormalize.*)
        test_scores.yml               every score on the test goals (agents.evaluate; the count)
        rl_model_<n>_steps.zip        checkpoints (+ rl_model_vecnormalize_<n>_steps.*)
"""

from __future__ import annotations

import re
from pathlib import Path

#: Shipped models (installed with the package), laid out as RL Zoo runs.
MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
#: Files of a run's parameter directory ``<run>/<env id>/``.
CONFIG_FILE = "config.yml"
ARGS_FILE = "args.yml"
MANIFEST_FILE = "manifest.yml"
STATS_NPZ = "vecnormalize.npz"
STATS_PKL = "vecnormalize.pkl"
#: Key of our run record inside the zoo's ``config.yml``.
RECORD_KEY = "softhand"
#: The run's record of its scores on the test goals (:mod:`agents.play.test_scores`).
TEST_SCORES_FILE = "test_scores.yml"
#: Best model of a run.
BEST_MODEL = "best_model"
#: The final model of a run whose best model was promoted (:mod:`agents.runs.promote`).
FINAL_MODEL = "final_model"
#: Checkpoint stems, ``rl_model_<env steps>_steps``.
CHECKPOINT = re.compile(r"rl_model_(\d+)_steps")


def stats_base(run_dir: Path, env_id: str, stem: str) -> Path:
    """Statistics of the model ``run_dir/<stem>.zip``, without suffix: a checkpoint's
    ``rl_model_vecnormalize_<n>_steps``; ``best_model_vecnormalize`` and
    ``final_model_vecnormalize`` where their ``.npz`` exists; else the final model's
    ``<env_id>/vecnormalize``."""
    match = CHECKPOINT.fullmatch(stem)
    if match:
        return run_dir / f"rl_model_vecnormalize_{match.group(1)}_steps"
    if stem in (BEST_MODEL, FINAL_MODEL) and (run_dir / f"{stem}_vecnormalize.npz").is_file():
        return run_dir / f"{stem}_vecnormalize"
    return run_dir / env_id / "vecnormalize"
