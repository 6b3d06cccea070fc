"""Every command refuses a wrong input or output location with ONE stderr line and exit code 2,
before any work; no command overwrites an earlier output without ``--force``.

The table runs each command as ``python -m <module>`` (a subprocess, as a user runs it), a few
at a time; each case must end within :data:`LIMIT_S`, far below the time of the work it
refuses (a 10**6-episode evaluation, a training, a demo: minutes to hours) and a few times the
import time of the command on a loaded 2-core machine (5-40 s measured).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: Wall-clock limit of one refused command (s).
LIMIT_S = 120.0

#: An output directory that cannot be created (no file can be written below /proc).
UNWRITABLE = "/proc/softhand-no-such-dir/x"


def _cases(tmp: Path) -> list[tuple[str, list[str], str]]:
    """(module, arguments, fragment of the one stderr line)."""
    evaluated = tmp / "evaluated"  # plots of an earlier evaluation, results.yml gone
    evaluated.mkdir()
    (evaluated / "trajectories.png").write_bytes(b"earlier png")
    (evaluated / "episode.gif").write_bytes(b"earlier gif")
    demo = tmp / "demo"
    (demo / "chapter5").mkdir(parents=True)
    (demo / "chapter5" / "trajectory.csv").write_text("edited by the user\n")
    figures = tmp / "figures"
    figures.mkdir()
    (figures / "fig2_6_stiffness.png").write_bytes(b"earlier figure")
    deep = tmp / "deep.json"
    deep.write_text("[" * 50_000 + "]" * 50_000)
    curve = tmp / "curve.png"
    bomb = tmp / "bomb.yml"  # 3 KB, 9**9 nodes once expanded
    bomb.write_text("a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 10))
        + "SoftHandTranslate-v0: {policy: MlpPolicy, n_timesteps: 1, env_wrapper: *a9}\n")
    big = tmp / "big.yml"
    big.write_text("# padding\n" * 200_000)
    translate = ["--env", "SoftHandTranslate-v0"]
    train = [*translate, "--no-progress-bar", "--log-folder", str(tmp / "logs")]
    evaluate = ["--policy", "model-based", *translate, "--n-episodes", "1"]
    pose = ["--policy", "model-based", "--grid", "3"]
    return [
        ("agents.train", [*train, "--seed", "-1"], "--seed"),
        ("agents.train", ["--env", "CarRacing-v3", "--log-folder", str(tmp / "logs")],
         "CarRacing-v3"),
        ("agents.train", [*translate, "--log-folder", UNWRITABLE], "not writable"),
        ("agents.train", [*translate, "--log-folder", str(ROOT / "agents" / "models"),
                          "--run-name", "SoftHandTranslate-v0_0"], "model folder"),
        ("agents.train", [*train, "--hyperparams", "normalize:{clip_obs: -1}"], "clip_obs"),
        ("agents.train", [*train, "--env-kwargs", 'grasp_setpoint_deg:"66"'],
         "grasp_setpoint_deg must be a pair"),
        ("agents.train", [*train, "--env-kwargs", "max_delta_deg:[1, 2]"], "max_delta_deg"),
        ("agents.train", [*train, "--conf-file", str(bomb)], "nodes (aliases)"),
        ("agents.train", [*train, "--conf-file", str(deep)], "nested deeper"),
        ("agents.distill", [*translate, "--teacher", "SoftHandTranslate-v0", "--conf-file",
                            str(big), "--log-folder", str(tmp / "logs")], "larger than"),
        ("agents.evaluate", ["--policy", "paper", "--n-episodes", "1000000"], "--n-episodes"),
        ("agents.evaluate", ["--policy", "paper", "--seed", "-1"], "--seed"),
        ("agents.evaluate", [*evaluate, "--out", UNWRITABLE], "not writable"),
        ("agents.evaluate", [*evaluate, "--out", str(evaluated)],
         "trajectories.png, episode.gif; pass --force"),
        ("agents.evaluate", [*evaluate, "--goals", str(deep), "--out", str(tmp / "e")],
         "JSON nested deeper than"),
        ("agents.evaluate", ["--model", str(tmp / "nothing.zip")], "not found"),
        ("agents.evaluate", ["--policy", "model-based", "--env", "CarRacing-v3"],
         "CarRacing-v3"),
        ("agents.demo", ["--seed", "-1", "--out", str(tmp / "d1")], "--seed"),
        ("agents.demo", ["--n-episodes", str(10**6), "--out", str(tmp / "d2")], "--n-episodes"),
        ("agents.demo", ["--out", str(demo)], "pass --force"),
        ("agents.demo", ["--out", UNWRITABLE], "not writable"),
        ("agents.distill", [*translate, "--teacher", "SoftHandTranslate-v0",
                            "--log-folder", UNWRITABLE], "not writable"),
        ("agents.distill", [*translate, "--teacher", "SoftHandTranslate-v0", "--iterations",
                            "0", "--log-folder", str(tmp / "logs")], "--iterations"),
        ("agents.pose_figures", [*pose, "--out", UNWRITABLE], "not writable"),
        ("agents.pose_figures", [*pose, "--grid", "0", "--out", str(tmp / "p")], "--grid"),
        ("agents.learning_curves", [str(tmp), "--out", UNWRITABLE + ".png"], "not writable"),
        ("agents.learning_curves", [str(tmp), "--out", str(curve)], "not a run directory"),
        ("agents.bench_train", ["--steps", "0"], "--steps"),
        ("agents.collect", ["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2",
                            "--seed", "10000", "--dataset-id", "softhand/pose/random-v0"],
         "meets the test goals"),
        ("agents.collect", ["--env", "SoftHandPose-v0", "--policy", "random", "--episodes", "2",
                            "--dataset-id", "softhand/translate/random-v0"],
         "named softhand/pose/"),
        ("agents.bc", ["--dataset", "softhand/pose/expert-v0", "--epochs", "0"], "--epochs"),
        ("agents.rllib_train", ["--env", "SoftHandReorient-v0", "--num-env-runners", "-1",
                                "--stop-timesteps", "10"], "--num-env-runners"),
        ("softhand_env.figures", ["contact", "--out", UNWRITABLE], "not writable"),
        ("softhand_env.figures", ["contact", "--out", str(figures)], "pass --force"),
        ("softhand_env.figures", ["dynamics", "--config", str(tmp / "none.yml"),
                                  "--out", str(tmp / "f2")], "not found"),
        ("softhand_env.figures", ["nosuch"], "invalid choice"),
        ("softhand_env.tools.soak", ["--num-envs", "0"], "--num-envs"),
        ("softhand_env.tools.soak", ["--env-id", "CarRacing-v3"], "CarRacing-v3"),
        ("softhand_env.play", ["--seed", "-1"], "--seed"),
        ("softhand_env.play", ["--env", "CarRacing-v3", "--max-frames", "1"], "CarRacing-v3"),
        ("softhand_env.tools.bench", ["--repeat", "0"], "--repeat"),
        ("softhand_env.tools.bench_env", ["--id", "CarRacing-v3"], "CarRacing-v3"),
        ("softhand_env.tools.bench_quasistatic", ["--repeat", "0"], "--repeat"),
        ("softhand_env.tools.observability", ["--env", "SoftHandPose-v1", "--sensor-model",
                                              "exact"], "invalid choice: 'exact'"),
        ("softhand_env.tools.observability", ["--env", "SoftHandPose-v1", "--obs-mode",
                                              "proprio", "--env-kwargs", "obs_mode:proprio"],
         "obs_mode is given twice"),
        ("softhand_env.tools.observability", ["--env", "CarRacing-v3", "--episodes", "2"],
         "CarRacing-v3"),
    ]


def _run(module: str, args: list[str]) -> tuple[int, str, float]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "SOFTHAND_TRACEBACK": ""}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-W", "ignore", "-m", module, *args], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=2 * LIMIT_S)
    return proc.returncode, proc.stderr, time.perf_counter() - t0


def test_every_command_refuses_bad_input_in_one_line_before_work(tmp_path):
    cases = _cases(tmp_path)
    snapshot = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    with ThreadPoolExecutor(max_workers=3) as pool:
        outcomes = list(pool.map(lambda c: _run(c[0], c[1]), cases))
    failures = []
    for (module, args, fragment), (code, err, seconds) in zip(cases, outcomes, strict=True):
        lines = err.splitlines()
        ok = (code == 2 and len(lines) == 1 and lines[0].startswith("error: ")
              and fragment in lines[0] and seconds < LIMIT_S)
        if not ok:
            failures.append(f"{module} {' '.join(args)}: exit {code}, {seconds:.0f} s, "
                            f"stderr {err[-600:]!r}")
    assert not failures, "\n".join(failures)
    # nothing was overwritten, nothing was created
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == snapshot
    for made in ("logs", "e", "d1", "d2", "p", "f2"):
        assert not (tmp_path / made).exists(), made
    assert not (ROOT / "agents" / "models" / "ppo" / "SoftHandTranslate-v0_0").exists()


def test_a_bug_keeps_its_traceback(tmp_path):
    """An unexpected exception type is not turned into one line (exit code 1, traceback)."""
    code = ("from softhand_env.cli import run_cli\n"
            "def main(argv):\n    raise KeyError('a bug')\n"
            "run_cli(main)\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert proc.returncode == 1 and "Traceback" in proc.stderr and "KeyError" in proc.stderr


def test_expected_errors_are_one_bounded_line(capsys):
    from softhand_env.cli import MAX_MESSAGE, run_cli
    from softhand_env.physics.hand import PhysicsError

    for exc in (ValueError("a\nb " * 10_000), PhysicsError("diverged", 1), MemoryError(),
                OSError(28, "No space left on device", "/x"), RecursionError()):
        def main(argv, exc=exc):
            raise exc
        with pytest.raises(SystemExit) as stop:
            run_cli(main, [])
        assert stop.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("error: ")
        assert len(err) <= len("error: ") + MAX_MESSAGE + 1
    import gymnasium as gym

    def other_id(argv):
        gym.make("CarRacing-v3")  # Box2D is not installed: DependencyNotInstalled
    with pytest.raises(SystemExit) as stop:
        run_cli(other_id, [])
    assert stop.value.code == 2 and capsys.readouterr().err.count("\n") == 1


def test_figures_overwrite_only_with_force(tmp_path, capsys):
    from softhand_env.figures import main

    out = tmp_path / "fig"
    assert main(["contact", "--out", str(out), "--dpi", "40"]) == 0
    first = (out / "fig2_6_stiffness.png").read_bytes()
    with pytest.raises(SystemExit) as stop:
        main(["contact", "--out", str(out), "--dpi", "41"])
    assert stop.value.code == 2 and "--force" in capsys.readouterr().err
    assert (out / "fig2_6_stiffness.png").read_bytes() == first
    assert main(["contact", "--out", str(out), "--dpi", "41", "--force"]) == 0
    assert (out / "fig2_6_stiffness.png").read_bytes() != first


def test_a_local_directory_shadowing_a_shipped_model_is_refused(tmp_path, monkeypatch):
    from agents.common.cli import UserError
    from agents.runs.loading import resolve_model

    monkeypatch.chdir(tmp_path)
    assert resolve_model("SoftHandTranslate-v0").env_id == "SoftHandTranslate-v0"
    (tmp_path / "SoftHandTranslate-v0").mkdir()
    with pytest.raises(UserError, match="shipped model and a local path"):
        resolve_model("SoftHandTranslate-v0")

