"""The test-goal counter of a run: how many times its model was scored on the test goals.

The evaluation protocol keeps two goal families apart: every choice (hyper-parameters, design,
checkpoint, seed) is made on the validation goals ``reset(seed=5000 + k)``
(:data:`VALIDATION_SEED`), and a final model is scored on the test goals ``reset(seed=10000 +
k)`` (:data:`TEST_SEED`) once. So that a reader can see how often a run's test figure was
looked at, ``agents.evaluate`` records every seeded evaluation that plays a test goal in the
run directory's ``test_scores.yml`` (:data:`~agents.runs.layout.TEST_SCORES_FILE`)::

    count: 2
    scores:
    - {date: '2026-12-02T04:50:00+00:00', model: SoftHandPose-v0.zip, n_episodes: 300,
       first_seed: 10000, success: 0.97, success_strict: 0.9}
    - ...

The file sits beside the model, outside ``config.yml``, so the checksums recorded there stay
valid. The shipped models (installed with the package, :data:`~agents.runs.layout.MODELS_DIR`)
are never written to: their test scores are the ones documented in ``docs/results.md``.
"""

from __future__ import annotations

import datetime
from pathlib import Path
from typing import Any

import yaml

from agents.common.cli import UserError
from agents.runs.layout import MODELS_DIR, TEST_SCORES_FILE

#: First seed of the validation goals (training's ``--eval-seed`` default).
VALIDATION_SEED = 5000
#: First seed of the test goals (``agents.evaluate``'s ``--seed`` default).
TEST_SEED = 10000
#: Size of the test family: the seeds from ``TEST_SEED`` to ``TEST_SEED + TEST_FAMILY_SIZE - 1``
#: (the largest goal set ``agents.evaluate`` plays from ``TEST_SEED``).
TEST_FAMILY_SIZE = 100_000


def plays_test_goals(seed: int, n_episodes: int, goals_file: str | None) -> bool:
    """Whether a goal set (episode k: ``reset(seed=seed + k)``, k < ``n_episodes``) plays a
    test goal: a seeded set (no ``--goals`` file) that meets the test family."""
    if goals_file is not None:
        return False
    return seed < TEST_SEED + TEST_FAMILY_SIZE and seed + n_episodes > TEST_SEED


def is_shipped(run_dir: Path) -> bool:
    """Whether ``run_dir`` is a shipped model's run (inside the installed package)."""
    try:
        Path(run_dir).resolve().relative_to(MODELS_DIR.resolve())
    except ValueError:
        return False
    return True


def read_scores(run_dir: Path) -> dict[str, Any]:
    """The run's ``test_scores.yml`` (``{"count": 0, "scores": []}`` when there is none);
    :class:`UserError` if it is not such a mapping."""
    path = Path(run_dir) / TEST_SCORES_FILE
    if not path.exists():
        return {"count": 0, "scores": []}
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise UserError(f"cannot read {path}: {exc}") from None
    ok = (isinstance(data, dict) and isinstance(data.get("count"), int)
          and isinstance(data.get("scores"), list) and data["count"] == len(data["scores"]))
    if not ok:
        raise UserError(f"{path} is not a test-score record (count: N, scores: a list of N)")
    return data


def record_score(run_dir: Path, model: str, n_episodes: int, first_seed: int,
                 summary: dict[str, float]) -> dict[str, Any]:
    """Add one test score to the run's ``test_scores.yml`` (count + 1, the date in ISO 8601
    UTC, the model file, the goal set and its success rates) and return the new record.
    ``ValueError`` for a shipped model's run (:func:`is_shipped`), which is never written."""
    if is_shipped(run_dir):
        raise ValueError(f"{run_dir} is a shipped model: its test scores are not recorded")
    data = read_scores(run_dir)
    entry = {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
             "model": model, "n_episodes": int(n_episodes), "first_seed": int(first_seed),
             "success": float(summary["success_rate"])}
    if "success_strict" in summary:
        entry["success_strict"] = float(summary["success_strict"])
    data = {"count": data["count"] + 1, "scores": [*data["scores"], entry]}
    path = Path(run_dir) / TEST_SCORES_FILE
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(yaml.safe_dump(data, sort_keys=False))
    tmp.replace(path)
    return data
