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
        shipped = (demo.MODELS / env_id / "model.zip").is_file()
        assert len(mine) == 1 + shipped, (env_id, mine)
        assert "model-based baseline" in mine[0]
    assert "residual on the loop plan" in "".join(body)
    assert (out / "summary.md").read_text().count("\n| SoftHand") == len(body)
