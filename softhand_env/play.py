"""``python -m softhand_env.play``: drive the hand from the keyboard in a pygame window.

::

    python -m softhand_env.play                          # SoftHandPose-v0, real time
    python -m softhand_env.play --env SoftHandTranslate-v0 --seed 3 --speed 0.5

Held keys move the finger set-points by ``--max-delta-deg`` per control period (the env's
``action_mode="delta"``; map in :mod:`softhand_env.envs.keys`): ``a`` / ``d`` move the left
fingertip left / right, ``j`` / ``l`` the right fingertip; one key per finger at a time
(``a`` + ``j``: both tips left, ``d`` + ``j``: squeeze). ``r`` starts a new episode (new goal),
``space`` pauses, ``Esc`` or closing the window quits. The window shows the hand, the object,
the goal (green outline), the set-points (thin lines) and a text overlay with the time, the
goal, the object's x and theta, the set-points and, when an episode ends, the reason.

The same key map drives :func:`gymnasium.utils.play.play` through the env's
``get_keys_to_action()``; that loop draws no overlay and needs ``fps`` and ``noop`` given::

    play(gym.make("SoftHandPose-v0", render_mode="rgb_array"), fps=50,
         noop=np.zeros(2, np.float32))
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from softhand_env.cli import ArgumentParser, CliError, run_cli
from softhand_env.envs.keys import action_from_keys
from softhand_env.figures.overlay import episode_caption, overlay_text

HELP_LINE = "a/d: left tip   j/l: right tip   r: new episode   space: pause   esc: quit"


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Command-line arguments; out-of-range values exit with code 2 and name the option."""
    p = ArgumentParser(prog="python -m softhand_env.play",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="SoftHandPose-v0", help="soft-hand env id")
    p.add_argument("--seed", type=int, default=None, help="seed of the first reset")
    p.add_argument("--speed", type=float, default=1.0,
                   help="simulated seconds per wall-clock second, in (0, 10] (default 1)")
    p.add_argument("--max-delta-deg", type=float, default=1.0,
                   help="set-point change per control period while a key is held (deg)")
    p.add_argument("--size", type=int, default=560, help="window size in px, 120..2000")
    p.add_argument("--max-frames", type=int, default=None,
                   help="quit after this many frames (default: run until closed)")
    args = p.parse_args(argv)
    if not (math.isfinite(args.speed) and 0 < args.speed <= 10):
        p.error(f"--speed must be in (0, 10] (got {args.speed})")
    if not 120 <= args.size <= 2000:
        p.error(f"--size must be in 120..2000 px (got {args.size})")
    if args.seed is not None and not 0 <= args.seed <= 2**32 - 1:
        p.error(f"--seed must be in [0, 2**32 - 1] (got {args.seed})")
    if args.max_frames is not None and args.max_frames < 1:
        p.error(f"--max-frames must be >= 1 (got {args.max_frames})")
    return args


class Teleop:
    """Keyboard teleoperation of one soft-hand env in a pygame window.

    Parameters
    ----------
    env : gymnasium.Env
        A soft-hand env made with ``render_mode="rgb_array"`` and ``action_mode="delta"``.
    seed : int or None
        Seed of the first reset (later resets continue the env's random stream).
    speed : float
        Simulated seconds per wall-clock second (1 = real time).
    """

    def __init__(self, env: Any, seed: int | None = None, speed: float = 1.0):
        import pygame

        if env.render_mode != "rgb_array":
            raise ValueError(f"Teleop needs render_mode='rgb_array' (got {env.render_mode!r})")
        self.keys = env.unwrapped.get_keys_to_action()  # raises unless action_mode="delta"
        self.env = env
        self.dt = float(env.unwrapped.dt)
        self.targets = tuple(t.name for t in env.unwrapped.task.targets)
        self.fps = speed / self.dt
        self.pressed: set[str] = set()
        self.running, self.paused = True, False
        self.steps = self.total_steps = self.episodes = 0
        self.ended: str | None = None
        self._pg = pygame
        pygame.display.init()  # display only: no audio
        pygame.display.set_caption(f"softhand_env.play: {env.spec.id if env.spec else 'env'}")
        self._reset(seed)
        frame = env.render()
        self.screen = pygame.display.set_mode((frame.shape[1], frame.shape[0]))
        self.clock = pygame.time.Clock()

    def _reset(self, seed: int | None = None) -> None:
        self.obs, self.info = self.env.reset(seed=seed)
        self.steps, self.ended = 0, None
        self.episodes += 1

    def handle(self, event: Any) -> None:
        """Apply one pygame event (key down/up, quit)."""
        pg = self._pg
        if event.type == pg.QUIT:
            self.running = False
        elif event.type == pg.KEYDOWN:
            name = pg.key.name(event.key)
            if event.key == pg.K_ESCAPE:
                self.running = False
            elif name == "r":
                self._reset()
            elif name == "space":
                self.paused = not self.paused
            else:
                self.pressed.add(name)
        elif event.type == pg.KEYUP:
            self.pressed.discard(pg.key.name(event.key))

    @property
    def action(self) -> np.ndarray:
        """Delta action (2,) of the keys held now."""
        return action_from_keys(self.pressed)

    def lines(self) -> list[str]:
        """Overlay text of the current frame."""
        info = self.info
        goal = info.get("goal", ()) if self.targets else ()
        out = episode_caption(self.steps * self.dt, self.targets, goal, info["object_pose"])
        u = np.degrees(info["setpoint"])
        out.append(f"set-points  θ1ᵈ = {u[0]:+.1f}°   θ2ᵈ = {u[1]:+.1f}°")
        if self.ended is not None:
            out.append(f"episode ended: {self.ended}; r: new episode")
        elif self.paused:
            out.append("paused (space)")
        return out

    def tick(self) -> None:
        """Handle pending events, step the env once (unless paused or ended), draw a frame."""
        for event in self._pg.event.get():
            self.handle(event)
        if not self.running:
            return
        if not self.paused and self.ended is None:
            self.obs, _, terminated, truncated, self.info = self.env.step(self.action)
            self.steps += 1
            self.total_steps += 1
            if terminated or truncated:
                self.ended = str(self.info.get("termination_reason") or "time limit")
        frame = overlay_text(self.env.render(), self.lines())
        frame = overlay_text(frame, [HELP_LINE], corner="bottom")
        surface = self._pg.surfarray.make_surface(np.ascontiguousarray(frame.swapaxes(0, 1)))
        self.screen.blit(surface, (0, 0))
        self._pg.display.flip()
        self.clock.tick(self.fps)

    def run(self, max_frames: int | None = None) -> dict[str, Any]:
        """Loop until quit (or ``max_frames`` frames); returns counts and the last set-points."""
        frames = 0
        while self.running and (max_frames is None or frames < max_frames):
            self.tick()
            frames += 1
        return {"frames": frames, "steps": self.total_steps, "episodes": self.episodes,
                "setpoint_deg": [float(v) for v in np.degrees(self.info["setpoint"])]}

    def close(self) -> None:
        self.env.close()
        self._pg.display.quit()


def _run(argv: Sequence[str] | None) -> int:
    args = parse_args(argv)
    import gymnasium as gym

    import softhand_env  # noqa: F401  (registers the ids)

    ours = sorted(k for k in gym.registry if k.startswith("SoftHand"))
    if args.env not in ours:  # never build another package's env
        raise CliError(f"--env {args.env!r} is not a soft-hand env ({', '.join(ours)})")
    env = gym.make(args.env, render_mode="rgb_array", render_width=args.size,
                   render_height=args.size, action_mode="delta",
                   max_delta_deg=args.max_delta_deg)
    try:
        import pygame  # noqa: F401
    except ModuleNotFoundError:
        env.close()
        raise CliError("teleoperation needs pygame: pip install 'softhand-env[render]'") from None
    teleop = Teleop(env, seed=args.seed, speed=args.speed)
    try:
        summary = teleop.run(args.max_frames)
    finally:
        teleop.close()
    print(f"{summary['episodes']} episode(s), {summary['steps']} steps")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the exit code (0). A wrong input (argument, env id, keyword)
    is one line on stderr and exit code 2 (:func:`softhand_env.cli.run_cli`)."""
    return int(run_cli(_run, argv))


if __name__ == "__main__":
    sys.exit(main())
