"""Success and final errors of episodes: the one success definition every evaluation uses.

:data:`SUCCESS_TOLERANCE`: |x err| < 1 mm, |theta err| < 1 deg at the END of the episode;
:func:`success_kwargs` gives the env keywords that set it, :func:`final_errors` the final
errors of an episode from its last ``info``, :func:`summarize` the table of a goal set.
:data:`STRICT_TOLERANCE` (0.5 mm / 0.5 deg) is the second, stricter rule (:func:`strict_success`);
:func:`wilson_interval` is the 95 % score interval of a success rate and :func:`success_text`
the way every success figure is printed (rate with its interval); :func:`is_failure` tells an
episode ended by a physical failure from one that ran out of time or succeeded.
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

#: The strict success rule: a success (above) whose final errors are also within 0.5 mm /
#: 0.5 deg; per controlled coordinate, its final-error key's tolerance.
STRICT_TOLERANCE: dict[str, float] = {"x": 0.5, "theta": 0.5}

#: Standard-normal quantile of the two-sided 95 % interval, Phi^-1(0.975).
Z95 = 1.959963984540054


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


def is_failure(reason: str | None) -> bool:
    """Whether an episode's ``info["termination_reason"]`` names a physical failure (slip,
    tension, over-compression, grasp lost, ...): not None (running, or ended by the time limit)
    and not ``"success"``."""
    return reason not in (None, "success")


def strict_success(success: bool, errors: dict[str, float], targets: Iterable[str]) -> bool:
    """Success under :data:`STRICT_TOLERANCE`: the episode succeeded under the benchmark's rule
    (``success``: ``info["is_success"]`` of its last step, false after a failed step) and each
    controlled coordinate's final error (``errors`` of :func:`final_errors`: mm, deg) is below
    0.5 mm / 0.5 deg. The goal-free task has no coordinate: its strict success is ``success``."""
    return bool(success) and all(errors[ERROR_KEYS[t]] < STRICT_TOLERANCE[t] for t in targets)


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a success rate: ``successes`` of ``n`` Bernoulli trials.

    Returns ``(low, high)`` as fractions in [0, 1], the set of rates p whose normal test
    |p_hat - p| <= z sqrt(p (1 - p) / n) accepts the observed rate p_hat = successes / n::

        centre = (p_hat + z^2 / (2n)) / (1 + z^2 / n)
        half = z / (1 + z^2 / n) * sqrt(p_hat (1 - p_hat) / n + z^2 / (4 n^2))

    ``z`` = 1.96 (default, :data:`Z95`) gives the 95 % interval. Unlike the Wald interval
    p_hat +- z sqrt(p_hat (1 - p_hat) / n) it stays inside [0, 1] and does not collapse at 0 / n
    or n / n (e.g. 100 / 100 -> (0.963, 1.0)). ``ValueError`` for n < 1, successes outside
    0 .. n or z <= 0.
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"wilson_interval needs n >= 1 trials (got {n!r})")
    if isinstance(successes, bool) or int(successes) != successes or not 0 <= successes <= n:
        raise ValueError(f"successes must be an integer in 0 .. {n} (got {successes!r})")
    if not (math.isfinite(z) and z > 0):
        raise ValueError(f"z must be positive and finite (got {z!r})")
    p = successes / n
    z2 = z * z
    denom = 1.0 + z2 / n
    centre = (p + z2 / (2 * n)) / denom
    half = z / denom * math.sqrt(p * (1.0 - p) / n + z2 / (4 * n * n))
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def success_count(rate: float, n: int) -> int:
    """Number of successes behind a success ``rate`` of ``n`` episodes (``rate * n``,
    rounded; ``ValueError`` if that is not an integer count within 1e-6)."""
    k = rate * n
    if not math.isfinite(k) or abs(k - round(k)) > 1e-6:
        raise ValueError(f"success rate {rate!r} of {n} episodes is not a count")
    return int(round(k))


def success_text(successes: int, n: int) -> str:
    """A success figure as every command prints it: ``"86.0 % (86/100, 95 % CI 77.9-91.5 %)"``
    (the rate, the count and the Wilson 95 % interval of :func:`wilson_interval`)."""
    low, high = wilson_interval(successes, n)
    return (f"{100 * successes / n:.1f} % ({successes}/{n}, 95 % CI "
            f"{100 * low:.1f}-{100 * high:.1f} %)")


def summary_success_text(summary: dict[str, float], key: str = "success_rate") -> str:
    """:func:`success_text` of a summary's success rate ``key`` over its ``n_episodes``
    (``"n/a (0 episodes)"`` for an empty goal set)."""
    n = int(summary["n_episodes"])
    if n < 1:
        return "n/a (0 episodes)"
    return success_text(success_count(summary[key], n), n)


def error_score(summary: dict[str, float], targets: Sequence[str]) -> float:
    """Mean over targets of (median final error / success tolerance): lower is better."""
    vals = [summary[f"median_{ERROR_KEYS[t]}"] / SUCCESS_TOLERANCE[t][1] for t in targets]
    return float(np.mean(vals)) if vals else 0.0
