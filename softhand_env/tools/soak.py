"""Soak test of the native vector env (memory, throughput, termination reasons).

Usage: ``python -m softhand_env.tools.soak --steps 1000000 --num-envs 512``.

Steps :class:`~softhand_env.envs.SoftHandVectorEnv` (``gym.make_vec(...,
vectorization_mode="vector_entry_point")``, NextStep autoreset) with seeded uniform random
actions and reports

* environment steps per second (``--steps`` counts environment steps, i.e. vector steps times
  ``--num-envs``, after a warm-up of ``--warmup`` vector steps that compiles and allocates),
* episodes ended (terminated + truncated), the termination reasons with their counts and the
  truncations,
* non-finite observations or rewards (must be 0),
* peak resident memory (``resource.getrusage``: ``ru_maxrss``) after the warm-up ("start") and
  at the end, their growth in percent, and the current RSS (``/proc/self/statm``) at both ends.

Memory must stay flat: the exit status is 1 if the peak RSS grows by more than ``--max-growth``
(default 5 %) or a non-finite value appeared, else 0; a wrong argument (out of its range, an
unknown env id) is exit status 2 with one line on stderr, before anything runs. Not part of
the default test run (a tiny smoke run is). ``--threads`` caps numba's worker threads (share
a busy machine politely).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np


def peak_rss_mib() -> float:
    """Peak resident set size of this process so far (MiB; ``ru_maxrss`` is KiB on Linux)."""
    scale = 1.0 / 1024**2 if sys.platform == "darwin" else 1.0 / 1024  # macOS reports bytes
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale


def current_rss_mib() -> float | None:
    """Current resident set size (MiB) from ``/proc/self/statm``; None where unavailable."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
    except (OSError, IndexError, ValueError):
        return None
    return pages * os.sysconf("SC_PAGE_SIZE") / 1024**2


@dataclass
class SoakResult:
    """Figures of one soak run (see module doc)."""

    env_id: str
    num_envs: int
    env_steps: int
    seconds: float
    steps_per_second: float
    episodes: int
    truncations: int
    termination_reasons: dict[str, int] = field(default_factory=dict)
    nonfinite: int = 0
    peak_rss_start_mib: float = 0.0
    peak_rss_end_mib: float = 0.0
    peak_rss_growth_percent: float = 0.0
    rss_start_mib: float | None = None
    rss_end_mib: float | None = None


def soak(
    env_id: str = "SoftHandReorient-v0",
    num_envs: int = 512,
    steps: int = 1_000_000,
    seed: int = 0,
    warmup: int = 20,
    report_every: float = 0.0,
) -> SoakResult:
    """Run the soak loop and return its figures (arguments as the command-line options)."""
    import gymnasium as gym

    import softhand_env  # noqa: F401  (registers the environments)

    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    space = envs.action_space
    assert isinstance(space, gym.spaces.Box)
    low, high = space.low.astype(np.float64), space.high.astype(np.float64)
    rng = np.random.default_rng(seed)
    reasons: Counter[str] = Counter()
    counts = {"episodes": 0, "truncations": 0, "nonfinite": 0}

    def run(n_vector_steps: int, progress: bool) -> None:
        last = time.perf_counter()
        for k in range(n_vector_steps):
            actions = rng.uniform(low, high).astype(np.float32)
            obs, rewards, terminated, truncated, info = envs.step(actions)
            if not (np.isfinite(obs).all() and np.isfinite(rewards).all()):
                counts["nonfinite"] += int((~np.isfinite(obs)).any(axis=1).sum())
                counts["nonfinite"] += int((~np.isfinite(rewards)).sum())
            done = terminated | truncated
            if done.any():
                counts["episodes"] += int(done.sum())
                counts["truncations"] += int((truncated & ~terminated).sum())
                ended = info["termination_reason"][terminated]  # None while running
                reasons.update(r for r in ended if r is not None)
            if progress and time.perf_counter() - last >= report_every:
                last = time.perf_counter()
                print(
                    f"[soak] {(k + 1) * num_envs:,} env steps, {counts['episodes']:,} episodes, "
                    f"peak RSS {peak_rss_mib():.1f} MiB",
                    file=sys.stderr,
                    flush=True,
                )

    envs.reset(seed=seed)
    run(warmup, progress=False)
    reasons.clear()
    counts.update(episodes=0, truncations=0, nonfinite=0)
    peak_start, rss_start = peak_rss_mib(), current_rss_mib()
    n_vector = math.ceil(steps / num_envs)
    t0 = time.perf_counter()
    run(n_vector, progress=report_every > 0)
    seconds = time.perf_counter() - t0
    peak_end, rss_end = peak_rss_mib(), current_rss_mib()
    envs.close()
    env_steps = n_vector * num_envs
    return SoakResult(
        env_id=env_id,
        num_envs=num_envs,
        env_steps=env_steps,
        seconds=seconds,
        steps_per_second=env_steps / seconds,
        episodes=counts["episodes"],
        truncations=counts["truncations"],
        termination_reasons=dict(reasons.most_common()),
        nonfinite=counts["nonfinite"],
        peak_rss_start_mib=peak_start,
        peak_rss_end_mib=peak_end,
        peak_rss_growth_percent=100.0 * (peak_end - peak_start) / peak_start,
        rss_start_mib=rss_start,
        rss_end_mib=rss_end,
    )


def format_result(r: SoakResult) -> str:
    """Human-readable report of a :class:`SoakResult`."""
    rss = ""
    if r.rss_start_mib is not None and r.rss_end_mib is not None:
        rss = f"\ncurrent RSS   {r.rss_start_mib:.1f} MiB -> {r.rss_end_mib:.1f} MiB"
    reasons = ", ".join(f"{k}: {v:,}" for k, v in r.termination_reasons.items()) or "none"
    return (
        f"soak {r.env_id}, {r.num_envs} envs (native vector env, random actions)\n"
        f"env steps     {r.env_steps:,} in {r.seconds:.1f} s = {r.steps_per_second:,.0f} steps/s\n"
        f"episodes      {r.episodes:,} ({r.truncations:,} truncated)\n"
        f"terminations  {reasons}\n"
        f"non-finite    {r.nonfinite}\n"
        f"peak RSS      {r.peak_rss_start_mib:.1f} MiB -> {r.peak_rss_end_mib:.1f} MiB "
        f"({r.peak_rss_growth_percent:+.2f} %)" + rss
    )


class _UsageError(Exception):
    """A wrong command-line argument: one line on stderr, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # type: ignore[override,unused-ignore]
        raise _UsageError(message)


def _check_args(args: argparse.Namespace) -> None:
    """Every argument in its documented range (``--help``), the env id registered."""
    import gymnasium as gym

    bounds = {"num_envs": (1, 65_536), "steps": (1, 10**11), "warmup": (0, 10**6),
              "seed": (0, 2**32 - 1), "max_growth": (0.0, 1e6), "report_every": (0.0, 1e6)}
    for name, (low, high) in bounds.items():
        value = getattr(args, name)
        if not (math.isfinite(value) and low <= value <= high):
            raise _UsageError(f"--{name.replace('_', '-')} must be in [{low}, {high}] "
                              f"(got {value})")
    if args.threads is not None:
        import numba

        top = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
        if not 1 <= args.threads <= top:
            raise _UsageError(f"--threads must be in [1, {top}] (got {args.threads})")
    import softhand_env  # noqa: F401  (registers the ids)

    ours = sorted(k for k in gym.registry if k.startswith("SoftHand"))
    if args.env_id not in ours:
        raise _UsageError(f"--env-id {args.env_id!r} is not a soft-hand env ({', '.join(ours)})")


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status: 0 soak passed, 1 soak failed (memory
    growth or non-finite values), 2 wrong arguments (one line on stderr, nothing run)."""
    parser = _Parser(description=__doc__.split("\n")[0])
    parser.add_argument("--env-id", default="SoftHandReorient-v0")
    parser.add_argument("--num-envs", type=int, default=512, help="1 .. 65536")
    parser.add_argument("--steps", type=int, default=1_000_000, help="environment steps, >= 1")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--warmup", type=int, default=20, help="vector steps before measuring")
    parser.add_argument("--threads", type=int, default=None,
                        help="numba threads, 1 .. the machine's (default all)")
    parser.add_argument("--max-growth", type=float, default=5.0, help="allowed peak RSS growth %%")
    parser.add_argument("--report-every", type=float, default=0.0, help="progress period (s)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    try:
        args = parser.parse_args(argv)
        _check_args(args)
    except _UsageError as exc:
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    if args.threads is not None:
        import numba

        numba.set_num_threads(args.threads)
    result = soak(
        args.env_id, args.num_envs, args.steps, args.seed, args.warmup, args.report_every
    )
    print(json.dumps(asdict(result), indent=2) if args.json else format_result(result))
    ok = result.nonfinite == 0 and result.peak_rss_growth_percent <= args.max_growth
    return 0 if ok else 1


if __name__ == "__main__":
    from softhand_env.cli import run_cli

    sys.exit(run_cli(main))
