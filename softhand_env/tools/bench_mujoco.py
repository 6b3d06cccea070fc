"""MuJoCo anchors of the speed table: simulated seconds per wall second of Gymnasium's
``Reacher-v5`` and ``Pusher-v5`` (single environment, random actions, resets included).

``mujoco`` is optional: nothing is installed or imported at import time, and the rows are
``None`` (reported as skipped) when it is absent. ``python -m softhand_env.tools.bench_mujoco``
prints them alone; :mod:`softhand_env.tools.bench_env` prints them beside the soft hand's.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from typing import Any

import numpy as np

#: The anchor environments.
ANCHOR_IDS = ("Reacher-v5", "Pusher-v5")


def mujoco_available() -> bool:
    """True if the ``mujoco`` package can be imported (it is not imported here)."""
    return importlib.util.find_spec("mujoco") is not None


def bench_simulated_rate(env_id: str, steps: int, repeats: int) -> float:
    """Simulated seconds per wall second (median of ``repeats`` runs) of ``gym.make(env_id)``
    over ``steps`` random-action steps, resets included."""
    import gymnasium as gym

    env = gym.make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = np.array([env.action_space.sample() for _ in range(steps)])
    base: Any = env.unwrapped
    dt = float(base.dt)
    rates = []
    for _ in range(repeats):
        env.reset(seed=0)
        t0 = time.perf_counter()
        for a in actions:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        rates.append(steps * dt / (time.perf_counter() - t0))
    env.close()
    return float(np.median(rates))


def bench_anchors(steps: int, repeats: int) -> dict[str, float | None]:
    """Simulated s / wall s of every :data:`ANCHOR_IDS` (None for all without ``mujoco``)."""
    if not mujoco_available():
        return {env_id: None for env_id in ANCHOR_IDS}
    return {env_id: bench_simulated_rate(env_id, steps, repeats) for env_id in ANCHOR_IDS}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=2000, help="env steps per timed run")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs; the median is shown")
    args = parser.parse_args(argv)
    for env_id, rate in bench_anchors(args.steps, args.repeats).items():
        text = "skipped (mujoco is not installed)" if rate is None else f"{rate:,.0f}"
        print(f"{env_id:<14}{text} simulated s / wall s")


if __name__ == "__main__":
    main()
