"""Rendering: a small NumPy rasteriser (``rgb_array``, headless) and a pygame window (``human``).

The frame shows the palm, both fingers at their current angles (thin dark lines: their
set-points), the hemispherical soft fingertips flattened by their normal deformation d_n
against the object, the object (width W_obj; its drawn height, 1.5 W_obj, is illustrative: the
model is planar and has no height) and the goal as a green outline of the object at the target
x and/or theta. pygame is imported only when a ``human`` window is opened.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from softhand_env.physics.params import HandParams

BACKGROUND = (246, 245, 240)
PALM = (95, 95, 105)
FINGER = (70, 110, 170)
FINGERTIP = (240, 150, 60)
OBJECT = (190, 60, 60)
GOAL = (30, 160, 60)
SETPOINT = (40, 40, 40)
#: Drawn object height relative to its width (illustrative).
OBJECT_ASPECT = 1.5


class Rasterizer:
    """Fill convex shapes into an RGB frame with world coordinates in metres.

    Parameters
    ----------
    width, height : int
        Frame size in pixels.
    xlim, ylim : (float, float)
        World window (m); the scale is uniform, the window centred.
    """

    def __init__(self, width: int, height: int, xlim: Sequence[float], ylim: Sequence[float]):
        self.width, self.height = int(width), int(height)
        xc, yc = 0.5 * (xlim[0] + xlim[1]), 0.5 * (ylim[0] + ylim[1])
        self.scale = min(width / (xlim[1] - xlim[0]), height / (ylim[1] - ylim[0]))  # px/m
        self.px = (np.arange(width) + 0.5 - 0.5 * width) / self.scale + xc
        self.py = (0.5 * height - (np.arange(height) + 0.5)) / self.scale + yc
        self.image = np.empty((height, width, 3), dtype=np.uint8)

    def clear(self, color: Sequence[int]) -> None:
        self.image[:] = color

    def _grid(self, xmin: float, xmax: float, ymin: float, ymax: float):
        i0 = int(np.searchsorted(self.px, xmin))
        i1 = int(np.searchsorted(self.px, xmax, side="right"))
        j0 = int(np.searchsorted(-self.py, -ymax))
        j1 = int(np.searchsorted(-self.py, -ymin, side="right"))
        if i0 >= i1 or j0 >= j1:
            return None
        return (slice(j0, j1), slice(i0, i1)), self.px[None, i0:i1], self.py[j0:j1, None]

    def polygon(self, points: np.ndarray, color: Sequence[int]) -> None:
        """Fill the convex polygon ``points`` (K, 2), any orientation."""
        pts = np.asarray(points, dtype=np.float64)
        x, y = pts[:, 0], pts[:, 1]
        area = np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)
        if area < 0:
            pts = pts[::-1]
        grid = self._grid(x.min(), x.max(), y.min(), y.max())
        if grid is None:
            return
        idx, X, Y = grid
        inside = np.ones((Y.shape[0], X.shape[1]), dtype=bool)
        for k in range(len(pts)):
            (ax, ay), (bx, by) = pts[k], pts[(k + 1) % len(pts)]
            inside &= (bx - ax) * (Y - ay) - (by - ay) * (X - ax) >= 0.0
        self.image[idx][inside] = color

    def segment(self, p: ArrayLike, q: ArrayLike, width_px: float, color) -> None:
        """A straight stroke from p to q (m), ``width_px`` pixels wide."""
        a, b = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
        d = b - a
        n = np.array([-d[1], d[0]]) / max(np.hypot(*d), 1e-12) * (0.5 * width_px / self.scale)
        self.polygon(np.array([a + n, b + n, b - n, a - n]), color)

    def disk(self, center, radius: float, color, cuts: Sequence[tuple] = ()) -> None:
        """Fill the disk ∩ {p : n·(p - center) <= c} for each (n, c) in ``cuts``."""
        cx, cy = center
        grid = self._grid(cx - radius, cx + radius, cy - radius, cy + radius)
        if grid is None:
            return
        idx, X, Y = grid
        dx, dy = X - cx, Y - cy
        inside = dx * dx + dy * dy <= radius * radius
        for (nx, ny), c in cuts:
            inside &= nx * dx + ny * dy <= c
        self.image[idx][inside] = color


def _rect(center, half_w: float, half_h: float, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    ex, ey = np.array([c, s]) * half_w, np.array([-s, c]) * half_h
    o = np.asarray(center, dtype=np.float64)
    return np.array([o + ex + ey, o - ex + ey, o - ex - ey, o + ex - ey])


def _outline(r: Rasterizer, corners: np.ndarray, width_px: float, color) -> None:
    for k in range(4):
        r.segment(corners[k], corners[(k + 1) % 4], width_px, color)


class SceneRenderer:
    """Draws the hand state into RGB frames (see module doc).

    Parameters
    ----------
    params : HandParams
        Geometry (nominal; the object width is taken per frame).
    width, height : int
        Frame size in pixels.
    """

    def __init__(self, params: HandParams, width: int, height: int):
        margin = params.a + 0.02
        span_x = params.W_fi + margin
        self.raster = Rasterizer(
            width, height, (-span_x, span_x), (-0.015, params.L + params.a + 0.03)
        )

    def frame(
        self,
        object_pose: np.ndarray,
        finger_angles: np.ndarray,
        deformation: np.ndarray,
        setpoint: np.ndarray,
        params: HandParams,
        goal_pose: tuple[float, float] | None = None,
    ) -> np.ndarray:
        """RGB frame (height, width, 3) uint8 of one hand (physics read-outs).

        Parameters
        ----------
        object_pose : ndarray, shape (3,)
            Object (x, y, theta) (m, m, rad).
        finger_angles : ndarray, shape (2,)
            Joint angles (rad).
        deformation : ndarray, shape (4,)
            d_n1, d_n2, d_t1, d_t2 (m).
        setpoint : ndarray, shape (2,)
            Set-points (rad), drawn as thin lines.
        goal_pose : (x, theta) or None
            Target drawn as an outline at (x, y_obj, theta) (m, rad).
        """
        r = self.raster
        r.clear(BACKGROUND)
        L, dfi, a, wfi = params.L, params.d_fi, params.a, params.W_fi
        r.polygon(_rect((0.0, -0.006), wfi + 2 * dfi, 0.006, 0.0), PALM)
        x, yo, th = (float(v) for v in object_pose)
        half_w, half_h = 0.5 * params.W_obj, 0.5 * OBJECT_ASPECT * params.W_obj
        r.polygon(_rect((x, yo), half_w, half_h, th), OBJECT)
        co, so = math.cos(th), math.sin(th)
        for i in range(2):
            sgn = -1.0 if i == 0 else 1.0  # (-1)^i in the paper's numbering
            root = np.array([-sgn * wfi, 0.0])
            t = float(finger_angles[i])
            ct, st = math.cos(t), math.sin(t)
            axis = np.array([sgn * st, ct])  # along the finger
            inward = np.array([sgn * ct, -st])  # towards the object
            tip = root + L * axis
            r.polygon(np.array([root + dfi * inward, tip + dfi * inward,
                                tip - dfi * inward, root - dfi * inward]), FINGER)
            centre = tip + dfi * inward  # fingertip centre O_i (Eqs 5.7-5.8)
            n_c = np.array([sgn * co, sgn * so])  # from O_i towards the object's face
            dn = max(float(deformation[i]), 0.0)
            r.disk(centre, a, FINGERTIP, cuts=(((-inward[0], -inward[1]), 0.0),
                                               ((n_c[0], n_c[1]), a - dn)))
            ts = setpoint[i]
            r.segment(root, root + L * np.array([sgn * math.sin(ts), math.cos(ts)]), 2.0,
                      SETPOINT)
        if goal_pose is not None:
            _outline(r, _rect((goal_pose[0], yo), half_w, half_h, goal_pose[1]), 3.0, GOAL)
        return r.image.copy()


class HumanViewer:
    """A pygame window showing frames at ``fps`` (pygame imported here, lazily)."""

    def __init__(self, width: int, height: int, fps: float):
        import pygame

        pygame.display.init()  # display only: no audio (pygame.init would open the mixer)
        pygame.display.set_caption("softhand_env")
        self._pygame = pygame
        self.screen = pygame.display.set_mode((width, height))
        self.clock = pygame.time.Clock()
        self.fps = fps

    def show(self, frame: np.ndarray) -> None:
        pg = self._pygame
        surface = pg.surfarray.make_surface(np.ascontiguousarray(frame.swapaxes(0, 1)))
        self.screen.blit(surface, (0, 0))
        pg.event.pump()
        pg.display.flip()
        self.clock.tick(self.fps)

    def close(self) -> None:
        self._pygame.display.quit()
