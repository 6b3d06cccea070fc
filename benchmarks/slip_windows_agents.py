"""Windowed friction of the scripted policies and the shipped agents (replayed at 1 ms).

::

    python benchmarks/slip_windows_agents.py                       # every source, 30 episodes
    python benchmarks/slip_windows_agents.py --sources pose loop-plan --episodes 10

Each source is played at its own control period, built as ``agents.evaluate`` builds it
(shipped model with its run's keywords and wrappers, or a scripted policy with the keywords it
declares, plus the benchmark's success tolerances), on the validation goals ``reset(seed=5000 +
k)``; its set-points are then replayed at 1 ms and judged on windows of 1-160 ms of physical
time by :mod:`softhand_env.tools.slip_windows` (which the package ships; this script lives
outside it because the package never imports the agents). Prints one Markdown table per source
and, with ``--out``, writes them to a file.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from softhand_env.tools import slip_windows as sw  # noqa: E402

#: Source name -> (what agents.evaluate is given: --model or --policy, value, --env).
SOURCES: dict[str, tuple[str, str, str | None]] = {
    "pose": ("model", "SoftHandPose-v0", None),
    "pose-random": ("model", "SoftHandPoseRandom-v0", None),
    "pose-residual": ("model", "SoftHandPose-v0_residual", None),
    "reorient": ("model", "SoftHandReorient-v0", None),
    "reorient-random": ("model", "SoftHandReorientRandom-v0", None),
    "translate": ("model", "SoftHandTranslate-v0", None),
    "loop-plan": ("policy", "loop-plan", "SoftHandPose-v0"),
    "model-based": ("policy", "model-based", "SoftHandPose-v0"),
    "handling": ("policy", "handling", None),
}
#: Grasp angles of the handling process (deg), the paper's five.
HANDLING_GRASPS = (2.4, 3.6, 4.8, 6.0, 7.2)


def build_source(name: str, grasp_deg: float = 6.0) -> tuple[Any, Any, str]:
    """(env factory, policy, description) of a source, chosen as ``agents.evaluate`` does."""
    from agents.common.env_factory import make_env
    from agents.play.choice import PolicyChoice, build
    from agents.runs.loading import ModelPolicy

    kind, value, env = SOURCES[name]
    choice = PolicyChoice(model=value if kind == "model" else None,
                          policy=value if kind == "policy" else None, env=env,
                          grasp_deg=grasp_deg)
    policy, env_id, kwargs, wrapper, label = build(choice)

    def make() -> Any:
        e = make_env(env_id, kwargs, wrapper)
        if isinstance(policy, ModelPolicy):
            policy.check_env(e)
        return e

    return make, policy, f"{env_id}, {label} ({value})"


def run(name: str, episodes: int, seed: int) -> tuple[str, list, list]:
    """Title, recordings and fine replays of one source."""
    if name == "handling":  # deterministic: one episode per grasp angle of the paper
        recs, reps = [], []
        for g in HANDLING_GRASPS:
            make, policy, title = build_source(name, g)
            r, p = sw.run_source(make, policy, [seed])
            recs += r
            reps += p
        return f"SoftHand-v0, handling process, grasp {list(HANDLING_GRASPS)} deg", recs, reps
    make, policy, title = build_source(name)
    recs, reps = sw.run_source(make, policy, [seed + k for k in range(episodes)])
    return title, recs, reps


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", nargs="+", choices=list(SOURCES), default=list(SOURCES))
    ap.add_argument("--episodes", type=int, default=30, help="episodes per source (default 30)")
    ap.add_argument("--seed", type=int, default=5000,
                    help="episode k: reset(seed=SEED + k) (default 5000, the validation goals)")
    ap.add_argument("--out", type=Path, default=None, help="also write the tables here")
    args = ap.parse_args(argv)
    if args.episodes < 1:
        ap.error("--episodes must be >= 1")
    import torch

    torch.set_num_threads(1)
    blocks = []
    for name in args.sources:
        t0 = time.perf_counter()
        title, recs, reps = run(name, args.episodes, args.seed)
        text = (sw.format_stats(f"### {name}: {title}, seeds {args.seed}+k", sw.analyse(reps))
                + "\n\n" + sw.format_checks(name, recs, reps)
                + f" ({time.perf_counter() - t0:.0f} s)\n")
        print(text, flush=True)
        blocks.append(text)
        if args.out is not None:
            args.out.write_text("\n".join(blocks))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
