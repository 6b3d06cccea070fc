"""The keywords of the soft-hand environments, each with its type, unit, range and doc, once.

:class:`EnvOptions` holds every ``gym.make(id, **kwargs)`` keyword of
:class:`~softhand_env.envs.SoftHandEnv` (and of the vector env) with its default; the
``metadata`` of each field is a :class:`Keyword`: one-line doc, unit, and what values it takes
(a range, choices, a flag, ...). From these records come

* the plain checks of every keyword (:func:`check_keyword`, :func:`check_options`: a
  ``ValueError`` naming the keyword, the value and the range), run by
  :func:`~softhand_env.envs.config.build_config` before anything is allocated, and by the
  modules that resolve a keyword (the task's YAML values, the randomisation preset, the
  observation layout, the action map) for the values they resolve;
* the Arguments table of the environments' docstrings and of the docs
  (:func:`arguments_table`, Markdown or reStructuredText).

Checks that relate several keywords or need the hand (the grasp set-points within the joint
range, ``control_dt`` a multiple of the RK4 substep, ``normalize_action=False`` only with
``action_mode="absolute"``, a task keyword the task does not use, randomisation ranges that
leave RK4's stable region) are code in the modules that resolve them
(:mod:`~softhand_env.envs.config`, :mod:`~softhand_env.envs.actions`,
:mod:`~softhand_env.envs.tasks`, :mod:`~softhand_env.envs.randomization`).
``SoftHandEnv.__init__`` spells the keywords out in its signature (for IDEs and type checkers);
a test keeps it identical to the fields (name, order, default, annotation).
"""

from __future__ import annotations

import inspect
import math
import reprlib
from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, field, fields, replace
from typing import Any

import numpy as np

from softhand_env.envs.task_configs import TASK_TARGETS
from softhand_env.physics.params import is_finite_real

#: Kinds of keyword values and what :meth:`Keyword.check` requires of each.
KINDS = {
    "number": "a real number in [low, high] (ends open per low_open / high_open)",
    "int": "an int (not a bool) in [low, high]",
    "flag": "True or False",
    "choice": "one of ``choices`` (strings)",
    "pair": "a pair of finite numbers, each in [low, high] (open ends per the flags)",
    "mapping": "a dict (its entries are checked where it is resolved)",
    "name": "a config name or path, checked where it is loaded",
}


@dataclass(frozen=True)
class Keyword:
    """How one environment keyword is documented and checked (a field's ``metadata``).

    Attributes
    ----------
    doc : str
        One line for the Arguments table.
    kind : str
        One of :data:`KINDS`.
    unit : str
        Unit of the value ("" if none), e.g. ``"deg"``, ``"s"``, ``"m"``, ``"px"``.
    low, high : float
        Range of a ``number``, ``int`` or ``pair`` (``math.inf``: unbounded; allowed as a
        value only for a closed infinite end).
    low_open, high_open : bool
        Whether the end itself is excluded.
    choices : tuple of str
        Allowed values of a ``choice`` (or the documented values of a ``name``).
    optional : bool
        ``None`` is allowed (its meaning is in ``doc``): set from the field's annotation.
    message : str
        Format of the error of an ``int`` out of range, overriding the kind's (fields
        ``name``, ``range``, ``value``): kept where users match a message worded otherwise.
    """

    doc: str
    kind: str
    unit: str = ""
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    optional: bool = False
    message: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {tuple(KINDS)} (got {self.kind!r})")

    @property
    def range_text(self) -> str:
        """The allowed values as the table and the error messages print them, e.g.
        ``"[0, 1)"``, ``"'delta', 'absolute'"``, ``"True, False"`` ("" when not plain)."""
        if self.kind in ("number", "int", "pair"):
            return (f"{'(' if self.low_open else '['}{self.low:g}, "
                    f"{self.high:g}{')' if self.high_open else ']'}")
        if self.kind == "flag":
            return "True, False"
        if self.kind == "choice" or self.choices:
            return ", ".join(repr(c) for c in self.choices)
        return ""

    def _in_range(self, value: float) -> bool:
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def _number_ok(self, value: Any) -> bool:
        if is_finite_real(value):
            return self._in_range(float(value))
        # an infinite value only at a closed infinite end (e.g. base_tolerance=math.inf)
        infinite = isinstance(value, (float, np.floating)) and math.isinf(value)
        return infinite and self._in_range(float(value)) and math.isinf(
            self.high if value > 0 else self.low)

    def check(self, name: str, value: Any) -> None:
        """Raise ``ValueError`` naming ``name``, ``value`` and the allowed values unless
        ``value`` is one of them (``None`` passes for an optional keyword)."""
        if value is None and self.optional:
            return
        rng = self.range_text
        if self.kind == "number":
            if not self._number_ok(value):
                raise ValueError(f"{name} must be a number in {rng} (got {value!r})")
        elif self.kind == "int":
            template = "{name} must be an int in {range} (got {value!r})"
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
                raise ValueError(template.format(name=name, range=rng, value=value))
            if not self._in_range(int(value)):
                template = self.message or template
                raise ValueError(template.format(name=name, range=rng, value=value))
        elif self.kind == "flag":
            if not isinstance(value, (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False (got {value!r})")
        elif self.kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                none = "None or " if self.optional else ""
                raise ValueError(
                    f"{name} must be {none}one of {self.choices} (got {value!r})"
                )
        elif self.kind == "pair":
            self._check_pair(name, value)
        elif self.kind == "mapping":
            if not isinstance(value, Mapping):
                raise ValueError(f"{name} must be None or a dict of HandParams fields "
                                 f"(got {value!r})")

    def _check_pair(self, name: str, value: Any) -> None:
        # a str is a sequence too ("66" would read as (6, 6)); so are str items ("6", "6")
        items = list(value) if isinstance(value, (list, tuple, np.ndarray)) else None
        if (items is None or len(items) != 2 or (isinstance(value, np.ndarray)
                                                 and value.ndim != 1)
                or not all(isinstance(v, (int, float, np.integer, np.floating))
                           and not isinstance(v, (bool, np.bool_)) for v in items)):
            raise ValueError(f"{name} must be a pair of numbers, a tuple or list of two "
                             f"(got {_short(value)})")
        try:
            a, b = (float(v) for v in items)
        except OverflowError:  # an int beyond a float's range
            raise ValueError(f"{name} must be finite (got {_short(value)})") from None
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ValueError(f"{name} must be finite (got {value!r})")
        if not (self._in_range(a) and self._in_range(b)):
            raise ValueError(f"{name} must be a pair of numbers in {self.range_text} "
                             f"(got {value!r})")


def _short(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (an error message never prints an
    unbounded value)."""
    text = reprlib.repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


_KEY = "keyword"


def _kw(default: Any, doc: str, kind: str, unit: str = "", **limits: Any) -> Any:
    """A dataclass field with default ``default`` and its :class:`Keyword` as metadata."""
    return field(default=default, metadata={_KEY: Keyword(doc, kind, unit, **limits)})


#: Bounds shared by several keywords: reward weights, randomisation half-widths.
MAX_WEIGHT = 1e6
_WEIGHT: dict[str, Any] = {"low": 0.0, "high": MAX_WEIGHT}
_HALF_WIDTH: dict[str, Any] = {"low": 0.0, "high": 1.0, "high_open": True}
_PRESET = "relative half-width (None: the ``randomize`` preset, {})"
_TASK = "(None: ``configs/tasks/<task>.yaml``)"


@dataclass(frozen=True)
class EnvOptions:
    """Keywords of the soft-hand environments (see the Arguments table of ``SoftHandEnv``).

    Each field's ``metadata["keyword"]`` is its :class:`Keyword` (doc, unit, range);
    :func:`arguments_table` renders them. Values are checked by
    :func:`~softhand_env.envs.config.build_config` (``ValueError`` naming the keyword); an
    unknown keyword raises ``TypeError`` here.
    """

    task: str = _kw("none", "the task (goal, reward, success)", "name",
                    choices=tuple(TASK_TARGETS))
    action_mode: str = _kw("delta", "``'delta'`` (set-point change) or ``'absolute'``",
                           "choice", choices=("delta", "absolute"))
    normalize_action: bool = _kw(True, "False (absolute only): action = set-points in rad",
                                 "flag")
    max_delta_deg: float = _kw(1.0, "largest set-point change per step; ctrl-cost unit",
                               "number", "deg", low=1e-3, high=30.0)
    joint_range_deg: tuple[float, float] = _kw(
        (-30.0, 30.0), "set-point limits (low, high), low < high", "pair", "deg",
        low=-90.0, high=90.0, low_open=True, high_open=True)
    control_dt: float = _kw(0.02, "control period, a positive multiple of the RK4 substep "
                            "(0.1 ms), at most 100,000 substeps", "number", "s",
                            low=0.0, high=1.0)
    obs_mode: str = _kw("proprio", "``'proprio_tactile'`` adds d_n, d_t", "choice",
                        choices=("proprio", "proprio_tactile"))
    history_len: int = _kw(1, "number of observation frames, newest first", "int",
                           low=1, high=100,
                           message="{name} must be in {range} (got {value!r})")
    onset_obs: bool = _kw(False, "append the joint encoders' reading at the start of the "
                          "grasp phase (fingertips touching the object, undeformed): 2 "
                          "entries after the frames", "flag")
    grasp_setpoint_deg: tuple[float, float] = _kw(
        (6.0, 6.0), "grasp set-points, first set-points; within ``joint_range_deg``", "pair",
        "deg", low=-90.0, high=90.0, low_open=True, high_open=True)
    grasp_duration: float = _kw(0.5, "grasp phase in reset (0: point-contact start), a "
                                "multiple of the RK4 substep, at most 1,000,000 substeps",
                                "number", "s", low=0.0, high=10.0)
    reset_noise_deg: float = _kw(0.0, "half-width of uniform noise on the grasp set-points",
                                 "number", "deg", low=0.0, high=10.0)
    hand: str = _kw("paper_ch5", "hand config name in ``configs/hand/`` or a YAML path",
                    "name")
    hand_overrides: dict[str, Any] | None = _kw(
        None, "HandParams fields (SI) replacing config values", "mapping")
    overcompression_ratio: float = _kw(0.5, "terminate when d_n >= ratio * a", "number",
                                       low=1e-3, high=1.0)
    ch_limit: float = _kw(0.001, "terminate when a holonomic residual exceeds this",
                          "number", "m", low=1e-12, high=1.0)
    base_tolerance: float = _kw(0.05, "allowed overshoot of tan theta_p past the base "
                                "(inf: off)", "number", low=0.0, high=math.inf)
    terminate_on_slip: bool = _kw(True, "end the episode on slip or tension (False: report "
                                  "only)", "flag")
    randomize: bool = _kw(False, "preset for every ``rand_*`` / ``obs_noise`` left at None",
                          "flag")
    rand_width: float | None = _kw(None, "object width, " + _PRESET.format(0.03), "number",
                                   **_HALF_WIDTH)
    rand_mass: float | None = _kw(None, "object mass, " + _PRESET.format(0.2), "number",
                                  **_HALF_WIDTH)
    rand_inertia: float | None = _kw(None, "object inertia, " + _PRESET.format(0.2),
                                     "number", **_HALF_WIDTH)
    rand_stiffness: float | None = _kw(None, "Young's modulus E, " + _PRESET.format(0.1),
                                       "number", **_HALF_WIDTH)
    rand_damping: float | None = _kw(None, "c_n and c_t, " + _PRESET.format(0.2), "number",
                                     **_HALF_WIDTH)
    rand_gains: float | None = _kw(None, "Kp, Kd, Ki, " + _PRESET.format(0.1), "number",
                                   **_HALF_WIDTH)
    rand_friction: float | None = _kw(None, "friction coefficient mu, "
                                      + _PRESET.format(0.2), "number", **_HALF_WIDTH)
    obs_noise: float | None = _kw(None, "observation noise std, scaled units (None: the "
                                  "``randomize`` preset, 0.01)", "number", low=0.0,
                                  high=10.0, high_open=True)
    setpoint_latency: int = _kw(0, "largest set-point latency, each episode draws 0..this",
                                "int", "steps", low=0, high=10)
    sensor_model: str = _kw("ideal", "joint and fingertip sensing: ``'ideal'`` (exact "
                            "read-outs) or ``'realistic'`` (``configs/sensors/realistic.yaml``"
                            "; see ``softhand_env.envs.sensors``)", "choice",
                            choices=("ideal", "realistic"))
    rand_sensors: bool = _kw(False, "draw each episode's torque-sensor gain within the sensor "
                             "model's ``torque_gain_tolerance`` (not with ``'ideal'``)", "flag")
    sensor_noise_scale: float = _kw(1.0, "multiplier of the sensor model's random errors: "
                                    "encoder, torque and tactile noise and the torque offset "
                                    "(0: quantised encoders, exact torques and fingertips; "
                                    "quantisation and ``rand_sensors`` gains unscaled; 1 "
                                    "with ``'ideal'``)", "number", low=0.0, high=10.0)
    goal_x_range_mm: float | None = _kw(None, "x* ~ U(-r, r) " + _TASK, "number", "mm",
                                        low=0.0, high=100.0, low_open=True)
    goal_theta_range_deg: float | None = _kw(None, "theta* ~ U(-r, r) " + _TASK, "number",
                                             "deg", low=0.0, high=90.0, low_open=True)
    x_tolerance_mm: float | None = _kw(None, "success tolerance on x " + _TASK, "number",
                                       "mm", low=0.0, high=100.0, low_open=True)
    theta_tolerance_deg: float | None = _kw(None, "success tolerance on theta " + _TASK,
                                            "number", "deg", low=0.0, high=90.0,
                                            low_open=True)
    x_scale_mm: float | None = _kw(None, "error scale of reward_goal for x " + _TASK,
                                   "number", "mm", low=0.0, high=1000.0, low_open=True)
    theta_scale_deg: float | None = _kw(None, "error scale of reward_goal for theta " + _TASK,
                                        "number", "deg", low=0.0, high=360.0, low_open=True)
    goal_weight: float | None = _kw(None, "weight of reward_goal " + _TASK, "number",
                                    **_WEIGHT)
    success_weight: float | None = _kw(None, "weight of reward_success " + _TASK, "number",
                                       **_WEIGHT)
    ctrl_weight: float | None = _kw(None, "weight of reward_ctrl " + _TASK, "number",
                                    **_WEIGHT)
    failure_weight: float | None = _kw(None, "weight of reward_failure " + _TASK, "number",
                                       **_WEIGHT)
    terminate_on_success: bool | None = _kw(None, "end the episode on success " + _TASK,
                                            "flag")
    render_mode: str | None = _kw(None, "None (no rendering), ``'rgb_array'`` or "
                                  "``'human'``", "choice", choices=("human", "rgb_array"))
    render_width: int = _kw(480, "frame width", "int", "px", low=16, high=4096)
    render_height: int = _kw(480, "frame height", "int", "px", low=16, high=4096)
    substep_limits: bool = _kw(False, "test over-compression, the fingertip base and "
                               "``ch_limit`` on every RK4 substep, ending the step there "
                               "(False: at the end of the control step, the v0 semantics)",
                               "flag")
    slip_window_ms: float | None = _kw(None, "physical-time window on which slip and tension "
                                       "are judged, a multiple of the RK4 substep (None: "
                                       "the control step, the v0 semantics)", "number", "ms",
                                       low=1.0, high=1000.0)
    setpoint_ramp_ms: float = _kw(0.0, "time over which a control step's set-points move "
                                  "from the previous ones to the new command, in stairs of "
                                  "10 ms (0: they jump at the step's start); a multiple of "
                                  "10 ms, at most ``control_dt``; needs ``slip_window_ms``",
                                  "number", "ms", low=0.0, high=1000.0)

    def as_dict(self) -> dict[str, Any]:
        """The keywords and their values, in signature order."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _keywords() -> dict[str, Keyword]:
    return {f.name: replace(f.metadata[_KEY], optional="None" in str(f.type))
            for f in fields(EnvOptions)}


#: Keyword name -> :class:`Keyword`, in signature order (``optional`` from the annotation).
KEYWORDS: dict[str, Keyword] = _keywords()


def check_keyword(name: str, value: Any, *, allow_none: bool = True) -> None:
    """Check ``value`` of keyword ``name`` against its :class:`Keyword` (``ValueError``
    naming the keyword, the value and the range). ``allow_none=False``: ``None`` is refused
    also for an optional keyword (a value being resolved, e.g. from a task's YAML)."""
    spec = KEYWORDS[name]
    (spec if allow_none else replace(spec, optional=False)).check(name, value)


def check_options(options: EnvOptions) -> None:
    """The plain checks of every keyword of ``options``, in signature order."""
    for name, spec in KEYWORDS.items():
        spec.check(name, getattr(options, name))


#: Largest ``num_envs`` of the vector env and largest ``max_episode_steps`` of either env.
MAX_NUM_ENVS = 65_536
MAX_EPISODE_STEPS = 10**7


def check_seed(seed: Any, name: str = "seed") -> int | None:
    """A ``reset`` seed as a Python int (None stays None), the same rule for the single and
    the vector env: an int of Python or NumPy (not a bool), ``>= 0``. ``TypeError`` for
    another type, ``ValueError`` for a negative value."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"{name} must be None or an int >= 0 (got {_short(seed)}, "
                        f"{type(seed).__name__})")
    if seed < 0:
        raise ValueError(f"{name} must be >= 0 (got {_short(seed)})")
    return int(seed)


def check_count(name: str, value: Any, high: int) -> int:
    """``value`` as an int in ``[1, high]`` (``num_envs``, ``max_episode_steps``): an int of
    Python or NumPy, not a bool; ``ValueError`` naming ``name`` otherwise."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer))
            or not 1 <= value <= high):
        raise ValueError(f"{name} must be an int in [1, {high}] (got {_short(value)})")
    return int(value)


def keyword_signature(function: Callable[..., Any]) -> inspect.Signature:
    """The signature of ``function`` with its ``**kwargs`` replaced by the keywords of
    :class:`EnvOptions` (keyword-only, with their defaults and annotations), for a callable
    that forwards ``**kwargs`` to ``EnvOptions``."""
    sig = inspect.signature(function)
    params = [p for p in sig.parameters.values() if p.kind is not p.VAR_KEYWORD]
    params += [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default,
                                 annotation=f.type) for f in fields(EnvOptions)]
    return sig.replace(parameters=params)


def _escape(text: str, fmt: str) -> str:
    if fmt == "markdown":
        return text.replace("``", "`").replace("|", "\\|")
    return text


def _type_text(annotation: str) -> str:
    return annotation.replace(" | ", " or ")


def arguments_table(fmt: str = "markdown", indent: int = 0) -> str:
    """The Arguments table of the environments: one row per keyword (name, type, default,
    unit, range, description), from :data:`KEYWORDS`.

    Parameters
    ----------
    fmt : str
        ``"markdown"`` (a pipe table, as in the env docstring) or ``"rst"`` (a list-table
        directive).
    indent : int
        Spaces before every line (to sit inside a docstring).
    """
    if fmt not in ("markdown", "rst"):
        raise ValueError(f"fmt must be 'markdown' or 'rst' (got {fmt!r})")
    header = ("Parameter", "Type", "Default", "Unit", "Range", "Description")
    rows = []
    for f in fields(EnvOptions):
        spec = KEYWORDS[f.name]
        default = f.default if f.default is not MISSING else None
        rows.append((f"`{f.name}`" if fmt == "markdown" else f"``{f.name}``",
                     _type_text(str(f.type)),
                     f"`{default!r}`" if fmt == "markdown" else f"``{default!r}``",
                     spec.unit, spec.range_text, _escape(spec.doc, fmt)))
    pad = " " * indent
    if fmt == "markdown":
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
    else:
        lines = [".. list-table::", "   :header-rows: 1", ""]
        for r in (header, *rows):
            lines.append("   * - " + r[0])
            lines += [("     - " + c).rstrip() for c in r[1:]]
    return "\n".join(pad + line if line else line for line in lines)
