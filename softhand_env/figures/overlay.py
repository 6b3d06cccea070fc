"""Text overlays on rendered frames: time, goal and object pose of an episode.

Used for the evaluation GIFs and the teleoperation window (``python -m softhand_env.play``).
Text is drawn with Pillow (a matplotlib dependency) in matplotlib's bundled DejaVu Sans, which
has the Greek letters; frames are ``(height, width, 3)`` uint8 arrays as returned by
``env.render()`` with ``render_mode="rgb_array"``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

TEXT = (20, 20, 20)
BOX = (255, 255, 255)
#: Opacity of the box behind the text (0-255).
BOX_ALPHA = 170


@lru_cache(maxsize=8)
def _font(size_px: int):
    from PIL import ImageFont

    try:
        import matplotlib

        path = f"{matplotlib.get_data_path()}/fonts/ttf/DejaVuSans.ttf"
        return ImageFont.truetype(path, size_px)
    except OSError:  # pragma: no cover - matplotlib installs ship the font
        return ImageFont.load_default(size_px)


def overlay_text(
    frame: np.ndarray, lines: Sequence[str], font_px: int | None = None, corner: str = "top"
) -> np.ndarray:
    """A copy of ``frame`` (H, W, 3) uint8 with ``lines`` on a light box in the left corner.

    ``corner`` is ``"top"`` (top-left) or ``"bottom"`` (bottom-left); ``font_px`` defaults to
    about 1/36 of the frame height (at least 9 px).
    """
    from PIL import Image, ImageDraw

    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise ValueError(f"frame must be (H, W, 3) uint8 (got {frame.shape}, {frame.dtype})")
    if corner not in ("top", "bottom"):
        raise ValueError(f"corner must be 'top' or 'bottom' (got {corner!r})")
    if not lines:
        return frame.copy()
    size = font_px or max(9, round(frame.shape[0] / 36))
    font = _font(size)
    base = Image.fromarray(frame).convert("RGBA")
    layer = Image.new("RGBA", base.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(layer)
    pad, gap = max(2, size // 4), max(1, size // 6)
    widths = [draw.textlength(line, font=font) for line in lines]
    height = len(lines) * (size + gap) - gap + 2 * pad
    top = 0 if corner == "top" else frame.shape[0] - height
    draw.rectangle((0, top, max(widths) + 2 * pad, top + height), fill=(*BOX, BOX_ALPHA))
    for k, line in enumerate(lines):
        draw.text((pad, top + pad + k * (size + gap)), line, font=font, fill=(*TEXT, 255))
    return np.asarray(Image.alpha_composite(base, layer).convert("RGB"))


def episode_caption(
    t: float,
    targets: Sequence[str] = (),
    goal: Sequence[float] = (),
    pose: Sequence[float] | None = None,
) -> list[str]:
    """Overlay lines for one frame: time, goal and the object's current x and theta.

    Parameters
    ----------
    t : float
        Time since the episode started (s).
    targets : sequence of ``"x"`` / ``"theta"``
        The task's goal coordinates, in the order of ``goal``; empty for the goal-free task.
    goal : sequence of float
        The goal in SI units (m for x, rad for theta), shape (len(targets),).
    pose : (x, y, theta) or None
        Object pose (m, m, rad); drawn as x and theta when given.
    """
    if len(goal) != len(targets):
        raise ValueError(f"goal has {len(goal)} entries for targets {tuple(targets)}")
    lines = [f"t = {t:.2f} s"]
    if targets:
        parts = [_format(name, value, star=True) for name, value in zip(targets, goal, strict=True)]
        lines.append("goal  " + "   ".join(parts))
    else:
        lines.append("no goal (replay)")
    if pose is not None:
        lines.append("now   " + "   ".join(
            (_format("x", pose[0], star=False), _format("theta", pose[2], star=False))))
    return lines


def _format(name: str, value: float, star: bool) -> str:
    mark = "*" if star else ""
    if name == "x":
        return f"x{mark} = {1e3 * value:+.1f} mm"
    if name == "theta":
        return f"θ{mark} = {math.degrees(value):+.1f}°"
    raise ValueError(f"unknown goal coordinate {name!r} (expected 'x' or 'theta')")


def annotate_episode(
    frames: Sequence[np.ndarray],
    dt: float,
    targets: Sequence[str] = (),
    goal: Sequence[float] = (),
    poses: Sequence[Sequence[float]] | None = None,
) -> list[np.ndarray]:
    """Frames of one episode with :func:`episode_caption` drawn on each.

    Frame k is taken ``k * dt`` seconds after the reset (frame 0 is the reset state), as
    recorded by rendering after ``reset`` and after every ``step``; ``poses`` (K, 3), if
    given, holds the object pose of each frame.
    """
    if poses is not None and len(poses) != len(frames):
        raise ValueError(f"{len(poses)} poses for {len(frames)} frames")
    return [
        overlay_text(frame, episode_caption(k * dt, targets, goal,
                                            None if poses is None else poses[k]))
        for k, frame in enumerate(frames)
    ]
