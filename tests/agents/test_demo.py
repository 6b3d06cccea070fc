"""The README's main job (agents.demo) runs end to end and writes what it promises."""

from __future__ import annotations

from agents import demo


def test_demo_writes_paper_figures_and_the_comparison_table(tmp_path):
    out = tmp_path / "demo"
    rows = demo.main(["--out", str(out), "--n-episodes", "2"])
    # chapter 5 (figures, CSV), its replay through gym.make, chapter 4
    for pattern in ("chapter5/*.png", "chapter5/*.csv", "chapter5_gym/episode.gif",
                    "chapter4/*.png"):
        assert list(out.glob(pattern)), pattern
    # one baseline row per goal task, one learned row per shipped model
    body = rows[2:]
    for env_id in demo.GOAL_ENVS:
        mine = [r for r in body if r.startswith(f"| {env_id} |")]
        assert len(mine) == 2, (env_id, mine)  # every goal task ships a learned agent
        assert "model-based baseline" in mine[0]
    pose = [r for r in body if r.startswith("| SoftHandPose-v0 |")][1]
    assert "blind student, no plan" in pose  # the default Pose model: learned without the plan
    assert (out / "summary.md").read_text().count("\n| SoftHand") == len(body)


def test_demo_exits_2_naming_a_missing_learned_model(tmp_path, monkeypatch, capsys):
    import pytest

    from agents.common import cli
    from agents.runs import loading

    monkeypatch.setattr(loading, "MODELS_DIR", tmp_path / "no_models")
    monkeypatch.setattr(demo, "shipped_models", loading.shipped_models)
    monkeypatch.setattr("agents.evaluate.main", lambda argv: {"success_rate": 1.0})
    monkeypatch.setattr("softhand_env.figures.main", lambda argv: None)
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(demo.main, ["--out", str(tmp_path / "demo"), "--n-episodes", "1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "no shipped model for SoftHandReorient-v0" in err
    assert "agents/models/<algo>/SoftHandReorient-v0_1/SoftHandReorient-v0.zip" in err


def test_demo_rerun_needs_force_and_passes_it_to_every_step(tmp_path, monkeypatch, capsys):
    """A rerun into an --out that holds files (a user's edited trajectory.csv) is refused
    before anything runs; with --force every step it runs is told to overwrite."""
    import pytest

    from agents.common import cli

    out = tmp_path / "demo"
    (out / "chapter5").mkdir(parents=True)
    edited = out / "chapter5" / "trajectory.csv"
    edited.write_text("edited by the user\n")
    calls: list[list[str]] = []
    monkeypatch.setattr("agents.evaluate.main",
                        lambda argv: calls.append(argv) or {"success_rate": 1.0})
    monkeypatch.setattr("softhand_env.figures.main", lambda argv: calls.append(argv))
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(demo.main, ["--out", str(out), "--n-episodes", "1"])
    assert exc.value.code == 2 and "pass --force" in capsys.readouterr().err
    assert calls == [] and edited.read_text() == "edited by the user\n"
    demo.main(["--out", str(out), "--n-episodes", "1", "--force"])
    assert len(calls) == 3 + 2 * len(demo.GOAL_ENVS)
    assert all("--force" in argv for argv in calls)
