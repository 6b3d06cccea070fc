"""Success and final errors of episodes: the one success definition every evaluation uses.

:data:`SUCCESS_TOLERANCE`: |x err| < 1 mm, |theta err| < 1 deg at the END of the episode;
:func:`success_kwargs` gives the env keywords that set it, :func:`final_errors` the final
errors of an episode from its last ``info``, :func:`summarize` the table of a goal set.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from agents.common.env_factory import task_targets

#: The benchmark's success rule (within 1 mm / 1 deg at the end of the episode), fixed:
#: per controlled coordinate, (env keyword, value).
SUCCESS_TOLERANCE: dict[str, tuple[str, float]] = {
    "x": ("x_tolerance_mm", 1.0),
    "theta": ("theta_tolerance_deg", 1.0),
}



def success_kwargs(env_id: str) -> dict[str, float]:
    """Env keywords that set the benchmark's success tolerance (1 mm / 1 deg) for ``env_id``."""
    return dict(SUCCESS_TOLERANCE[t] for t in task_targets(env_id))


def final_errors(info: dict[str, Any], targets: Iterable[str]) -> dict[str, float]:
    """Final |x - x*| (mm) and |theta - theta*| (deg) from an episode's last ``info``.

    Only the controlled coordinates (``targets``, in goal order) are returned, as
    ``{"x_mm": ..., "theta_deg": ...}``.
    """
    targets = tuple(targets)
    if not targets:
        return {}
    pose, goal = np.asarray(info["object_pose"]), np.asarray(info["goal"])
    out = {}
    for name, g in zip(targets, goal, strict=True):
        if name == "x":
            out["x_mm"] = abs(float(pose[0]) - float(g)) * 1e3
        else:
            out["theta_deg"] = math.degrees(abs(float(pose[2]) - float(g)))
    return out


#: Controlled coordinate -> key of its final error.
ERROR_KEYS = {"x": "x_mm", "theta": "theta_deg"}


def summarize(
    targets: Sequence[str],
    successes: Sequence[bool],
    errors: Sequence[dict[str, float]],
    returns: Sequence[float] | None = None,
    lengths: Sequence[int] | None = None,
) -> dict[str, float]:
    """Success rate, median / mean / max final errors, mean return and length of episodes."""
    out: dict[str, float] = {"n_episodes": len(successes)}
    out["success_rate"] = float(np.mean(successes)) if len(successes) else math.nan
    for name in targets:
        key = ERROR_KEYS[name]
        e = np.array([err[key] for err in errors])
        out[f"median_{key}"] = float(np.median(e))
        out[f"mean_{key}"] = float(np.mean(e))
        out[f"max_{key}"] = float(np.max(e))
    if returns is not None:
        out["mean_return"] = float(np.mean(returns))
    if lengths is not None:
        out["mean_length"] = float(np.mean(lengths))
    return out


def error_score(summary: dict[str, float], targets: Sequence[str]) -> float:
    """Mean over targets of (median final error / success tolerance): lower is better."""
    vals = [summary[f"median_{ERROR_KEYS[t]}"] / SUCCESS_TOLERANCE[t][1] for t in targets]
    return float(np.mean(vals)) if vals else 0.0
