"""Task defaults from ``configs/tasks/<task>.yaml`` (light: PyYAML only, used at registration).

Each file maps :class:`~softhand_env.envs.SoftHandEnv` task keywords (units in the key names)
to their defaults, plus ``max_episode_steps`` (the ``TimeLimit`` of the registered id).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

TASK_CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs" / "tasks"

#: Task name -> controlled object coordinates.
TASK_TARGETS: dict[str, tuple[str, ...]] = {
    "none": (),
    "reorient": ("theta",),
    "translate": ("x",),
    "pose": ("x", "theta"),
}


def load_task_config(task: str) -> dict[str, Any]:
    """The YAML defaults of ``task`` as a dict (``ValueError`` for an unknown task)."""
    import yaml

    if not isinstance(task, str) or task not in TASK_TARGETS:
        raise ValueError(f"unknown task {task!r}; choose one of {sorted(TASK_TARGETS)}")
    path = TASK_CONFIG_DIR / f"{task}.yaml"
    with path.open() as fh:
        data = yaml.safe_load(fh) or {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping")
    return data
