"""benchmarks/v0_v1_table.py: each row played on its -v0 and its -v1 id, the same goals."""

from __future__ import annotations

import pytest

from tests.tools.conftest import benchmark_script

pytest.importorskip("stable_baselines3")


@pytest.fixture(scope="module")
def table():
    with benchmark_script("v0_v1_table") as module:
        yield module


def test_rows_cover_the_shipped_models_and_their_ids(table):
    from agents.runs.layout import MODELS_DIR  # the shipped models' folder

    # the models trained on -v0 (the -v1 models are scored on their own id, docs/results.md)
    shipped = {p.name.removesuffix("_1") for p in (MODELS_DIR / "ppo").iterdir()
               if p.is_dir() and "-v0" in p.name}
    models = {r.value for r in table.ROWS.values() if r.kind == "model"}
    assert models == shipped
    import gymnasium as gym

    import softhand_env  # noqa: F401

    for row in table.ROWS.values():
        assert row.v0_id.endswith("-v0") and row.v1_id == row.v0_id[:-3] + "-v1"
        assert row.v1_id in gym.registry
        # a shipped model is played on -v1 off its signature, a scripted policy on -v1 as is
        assert ("--allow-off-signature" in row.argv(row.v1_id)) == (row.kind == "model")
        assert "--allow-off-signature" not in row.argv(row.v0_id)


def test_misses_are_counted_by_reason(table):
    episodes = [{"success": True, "termination_reason": "success"},
                {"success": False, "termination_reason": "slip"},
                {"success": False, "termination_reason": None},
                {"success": False, "termination_reason": "contact_past_base"},
                {"success": False, "termination_reason": "slip"}]
    assert table.misses_of(episodes) == {"slip": 2, "contact past base": 1,
                                         "out of tolerance": 1}
    assert list(table.misses_of(episodes)) == ["slip", "contact past base", "out of tolerance"]


def test_table_of_a_model_and_a_baseline_on_the_same_goals(table, tmp_path, capsys):
    out = tmp_path / "t.md"
    assert table.main(["--rows", "translate", "translate-model-based", "--n-episodes", "2",
                       "--seed", "5000", "--results", str(tmp_path / "r"), "--out",
                       str(out)]) == 0
    text = out.read_text()
    lines = text.splitlines()
    assert lines[0] == table.HEADER and len(lines) == 4
    assert all(line.count("|") == table.HEADER.count("|") for line in lines)
    assert "| nominal | Translate | PPO (`SoftHandTranslate-v0`) | 2 |" in lines[2]
    assert "| nominal | Translate | model-based (`model-based`) | 2 |" in lines[3]
    import yaml

    def record(value, env_id):
        return yaml.safe_load((tmp_path / "r" / value / env_id / "results.yml").read_text())

    v0 = record("SoftHandTranslate-v0", "SoftHandTranslate-v0")
    v1 = record("SoftHandTranslate-v0", "SoftHandTranslate-v1")
    assert v0["benchmark"] is True and v0["off_signature"] == []
    assert v1["benchmark"] is False
    assert any(f.startswith("sensor_model") for f in v1["off_signature"])
    # the same goals on both ids
    assert [e["goal"] for e in v0["episodes"]] == [e["goal"] for e in v1["episodes"]]
    assert [e["seed"] for e in v1["episodes"]] == [5000, 5001]
    assert record("model-based", "SoftHandTranslate-v1")["benchmark"] is True
    assert "off-signature: env_id" in capsys.readouterr().err
    # the output is not overwritten without --force
    from softhand_env.cli import CliError

    with pytest.raises(CliError, match="--force"):
        table.main(["--rows", "translate", "--n-episodes", "1", "--out", str(out)])
