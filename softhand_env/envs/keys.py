"""Keyboard map for teleoperation: keys move the finger set-points.

Each key moves one fingertip in the direction of the key on the keyboard, one step of
``max_delta_deg`` per control period while it is held (``action_mode="delta"``):

===  =========  ==================================  ===========
key  finger     set-point change                    tip moves
===  =========  ==================================  ===========
a    2 (left)   theta_2^d -= max_delta (opens)      left
d    2 (left)   theta_2^d += max_delta (closes)     right
j    1 (right)  theta_1^d += max_delta (closes)     left
l    1 (right)  theta_1^d -= max_delta (opens)      right
===  =========  ==================================  ===========

One key per finger may be held at a time: ``a`` + ``j`` moves both tips left (the object
rolls and translates left), ``d`` + ``l`` both right, ``d`` + ``j`` squeezes, ``a`` + ``l``
releases. :func:`keys_to_action` returns the map in the format of
:func:`gymnasium.utils.play.play` (key tuples to actions); :func:`action_from_keys` turns any
set of held keys into the action (opposite keys of one finger cancel).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable

import numpy as np

#: key -> (action index, sign): index 0 is finger 1 (right), index 1 finger 2 (left).
FINGER_KEYS: dict[str, tuple[int, float]] = {
    "a": (1, -1.0),
    "d": (1, +1.0),
    "j": (0, +1.0),
    "l": (0, -1.0),
}

#: Action when no key is held (keep both set-points).
NOOP = np.zeros(2, dtype=np.float32)


def action_from_keys(pressed: Iterable[str]) -> np.ndarray:
    """Delta action, shape (2,) float32 in [-1, 1], for the held key names ``pressed``.

    Keys outside :data:`FINGER_KEYS` are ignored; two opposite keys of one finger cancel.
    """
    action = np.zeros(2, dtype=np.float64)
    for key in set(pressed):
        if key in FINGER_KEYS:
            index, sign = FINGER_KEYS[key]
            action[index] += sign
    return action.astype(np.float32)


def keys_to_action(action_mode: str = "delta") -> dict[tuple[str, ...], np.ndarray]:
    """Key combinations -> delta actions (shape (2,) float32), for ``gymnasium.utils.play``.

    Every single key and every pair of one key per finger is listed (key tuples sorted).
    Only ``action_mode="delta"`` is supported: in the absolute modes an action is a position,
    which a fixed key map cannot hold; a ``ValueError`` says so.
    """
    if action_mode != "delta":
        raise ValueError(
            f"keyboard teleoperation needs action_mode='delta' (got {action_mode!r}): keys "
            "step the set-points, they cannot hold an absolute position"
        )
    by_finger: dict[int, list[str]] = {}
    for key, (index, _) in FINGER_KEYS.items():
        by_finger.setdefault(index, []).append(key)
    combos: list[tuple[str, ...]] = [(key,) for key in FINGER_KEYS]
    combos += [tuple(sorted(pair)) for pair in itertools.product(*by_finger.values())]
    return {combo: action_from_keys(combo) for combo in combos}
