"""The environment keywords have one source: the fields of EnvOptions and their Keyword records
(signatures, checks and the Arguments tables follow them)."""

from __future__ import annotations

import inspect
import math
from dataclasses import fields

import gymnasium as gym
import pytest

from softhand_env.envs import SoftHandEnv, SoftHandVectorEnv
from softhand_env.envs.options import (
    KEYWORDS,
    KINDS,
    EnvOptions,
    arguments_table,
    check_keyword,
)

FIELDS = fields(EnvOptions)
RANGED = sorted(n for n, k in KEYWORDS.items() if k.kind in ("number", "int"))


def test_single_env_signature_is_the_fields_in_name_order_default_and_annotation():
    params = list(inspect.signature(SoftHandEnv.__init__).parameters.values())[1:]
    assert [(p.name, p.default, p.annotation) for p in params] == [
        (f.name, f.default, f.type) for f in FIELDS]


def test_vector_env_signature_is_its_own_keywords_then_the_fields():
    params = list(inspect.signature(SoftHandVectorEnv.__init__).parameters.values())[1:]
    assert [p.name for p in params[:3]] == ["num_envs", "max_episode_steps", "autoreset_mode"]
    assert [(p.name, p.default, p.annotation, p.kind) for p in params[3:]] == [
        (f.name, f.default, f.type, inspect.Parameter.KEYWORD_ONLY) for f in FIELDS]
    # the signature documents what the constructor takes: an unknown keyword is refused
    with pytest.raises(TypeError, match="colour"):
        SoftHandVectorEnv(num_envs=1, colour="red")


@pytest.mark.parametrize("env_cls", [SoftHandEnv, SoftHandVectorEnv])
def test_docstring_arguments_table_is_the_generated_one(env_cls):
    table = arguments_table("markdown", indent=4)
    assert table in env_cls.__doc__ and "{ARGUMENTS_TABLE}" not in env_cls.__doc__
    rows = [line for line in table.splitlines() if line.strip().startswith("| `")]
    assert [r.split("`")[1] for r in rows] == [f.name for f in FIELDS]


def test_rst_table_has_a_row_per_keyword():
    rst = arguments_table("rst")
    assert rst.startswith(".. list-table::")
    assert [line[len("   * - ``"):-2] for line in rst.splitlines()
            if line.startswith("   * - ``")] == [f.name for f in FIELDS]
    with pytest.raises(ValueError, match="fmt"):
        arguments_table("html")


def test_every_keyword_has_a_doc_a_known_kind_and_numeric_ranges():
    assert list(KEYWORDS) == [f.name for f in FIELDS]
    for name, spec in KEYWORDS.items():
        assert spec.doc and spec.kind in KINDS, name
        assert spec.optional == ("None" in str(next(f for f in FIELDS if f.name == name).type))
        if spec.kind in ("number", "int"):
            assert math.isfinite(spec.low), name
            assert math.isfinite(spec.high) or name == "base_tolerance", name
    assert KEYWORDS["base_tolerance"].high == math.inf  # inf switches the check off


def _outside(spec) -> list[float | int]:
    """The nearest values beyond each finite end of a range (the end itself if open)."""
    if spec.kind == "int":
        return [int(spec.low) - 1, int(spec.high) + 1]
    out = [spec.low if spec.low_open else math.nextafter(spec.low, -math.inf)]
    if math.isfinite(spec.high):
        out.append(spec.high if spec.high_open else math.nextafter(spec.high, math.inf))
    return out


@pytest.mark.parametrize("name", RANGED)
def test_range_checks_come_from_the_keyword_record(name):
    spec = KEYWORDS[name]
    for value in _outside(spec):
        with pytest.raises(ValueError) as info:
            check_keyword(name, value)
        msg = str(info.value)
        assert name in msg and repr(value) in msg and spec.range_text in msg, msg
    for end, is_open in ((spec.low, spec.low_open), (spec.high, spec.high_open)):
        if not is_open:  # a closed end is allowed (math.inf included: base_tolerance)
            check_keyword(name, int(end) if spec.kind == "int" else end)
    for wrong in ("1", True, math.nan):
        with pytest.raises(ValueError, match=name):
            check_keyword(name, wrong)
    if spec.optional:
        check_keyword(name, None)
        with pytest.raises(ValueError, match=name):
            check_keyword(name, None, allow_none=False)


def test_env_applies_the_keyword_ranges_and_the_task_configs_meet_them(monkeypatch):
    """An env refuses a value just outside a recorded range, naming it; the values in the
    task YAMLs go through the same check (a bad one is refused naming its keyword)."""
    with pytest.raises(ValueError, match=r"reset_noise_deg must be a number in \[0, 10\]"):
        SoftHandEnv(reset_noise_deg=10.5)
    with pytest.raises(ValueError, match=r"obs_noise must be a number in \[0, 10\)"):
        SoftHandEnv(obs_noise=10.0)
    SoftHandEnv(task="reorient", reset_noise_deg=10.0, history_len=100)  # closed ends
    from softhand_env.envs import tasks

    real = tasks.load_task_config
    monkeypatch.setattr(tasks, "load_task_config",
                        lambda task: {**real(task), "theta_scale_deg": 400.0})
    with pytest.raises(ValueError, match=r"theta_scale_deg must be a number in \(0, 360\]"):
        gym.make("SoftHandReorient-v0")
