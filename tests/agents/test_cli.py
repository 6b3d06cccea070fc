"""Command-line tools: every wrong argument or config value is one line on stderr and exit
code 2, found before anything is written (no run directory, no results) or run."""

from __future__ import annotations

import json

import pytest
import yaml

from agents import evaluate, train
from agents.common import cli


def _exit_2(capsys, main, argv, fragment):
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(main, argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err


TRAIN = ["--env", "SoftHandTranslate-v0", "--no-progress-bar", "--verbose", "0",
         "--eval-freq", "0", "--save-freq", "0", "--n-timesteps", "64"]


@pytest.mark.parametrize(
    "extra,fragment",
    [
        (["--hyperparams", "policy:NopePolicy"], "cannot build PPO"),
        (["--hyperparams", "normalize:{bogus: 1}"], "bogus"),
        (["--hyperparams", "policy_kwargs:{net_arch: abc}"], "net_arch must be a list"),
        (["--hyperparams", "policy_kwargs:dict(net_arch=__import__('os'))"], "unsupported"),
        (["--hyperparams", "learning_rate:abc"], "learning_rate: bad value 'abc'"),
        (["--hyperparams", "n_steps:0"], "n_steps must be an int in [1, 1e+06]"),
        (["--hyperparams", "n_steps:1000000000"], "n_steps must be an int"),
        (["--hyperparams", "gamma:.nan"], "gamma must be a number in [0, 1]"),
        (["--hyperparams", "batch_size:true"], "batch_size must be an int"),
        (["--hyperparams", "n_envs:0"], "n_envs must be an int"),
        (["--hyperparams", "env_wrapper:pydoc.pipepager"], "refused"),
        (["--seed", "-1"], "--seed must be in"),
        (["--torch-threads", "0"], "--torch-threads must be in"),
        (["--eval-episodes", "0"], "--eval-episodes must be in"),
        (["--n-timesteps", "0"], "--n-timesteps must be in"),
        (["--run-name", "../x"], "--run-name must be one directory name"),
        (["--device", "tpu"], "invalid choice"),
        (["--bogus"], "unrecognized arguments"),
    ],
)
def test_train_rejects_bad_values_before_writing_anything(tmp_path, capsys, extra, fragment):
    _exit_2(capsys, train.main, [*TRAIN, "--log-folder", str(tmp_path / "logs"), *extra],
            fragment)
    assert not (tmp_path / "logs").exists()  # no orphan run directory


def test_train_log_folder_that_is_a_file(tmp_path, capsys):
    (tmp_path / "f").write_text("")
    _exit_2(capsys, train.main, [*TRAIN, "--log-folder", str(tmp_path / "f")], "not a directory")


EVAL = ["--policy", "model-based", "--env", "SoftHandReorient-v0", "--n-episodes", "1",
        "--no-plots"]


@pytest.mark.parametrize(
    "extra,fragment",
    [
        (["--seed", "-1"], "--seed must be in"),
        (["--torch-threads", "0"], "--torch-threads must be in"),
        (["--n-episodes", "0"], "--n-episodes must be in"),
        (["--gif-size", "0"], "--gif-size must be in"),
        (["--gif-episode", "3"], "--gif-episode"),
        (["--nope"], "unrecognized arguments"),
    ],
)
def test_evaluate_rejects_bad_arguments(tmp_path, capsys, extra, fragment):
    _exit_2(capsys, evaluate.main, [*EVAL, "--out", str(tmp_path / "o"), *extra], fragment)
    assert not (tmp_path / "o").exists()


def test_evaluate_out_naming_a_file_fails_before_the_evaluation(tmp_path, capsys, monkeypatch):
    (tmp_path / "f").write_text("")
    monkeypatch.setattr(evaluate, "evaluate", lambda *a, **k: pytest.fail("evaluated"))
    _exit_2(capsys, evaluate.main, [*EVAL, "--out", str(tmp_path / "f")], "not a directory")


def test_evaluate_never_overwrites_results_silently(tmp_path, capsys, monkeypatch):
    out = tmp_path / "o"
    evaluate.main([*EVAL, "--out", str(out)])
    first = (out / "results.yml").read_text()
    _exit_2(capsys, evaluate.main, [*EVAL, "--out", str(out), "--seed", "7"], "--force")
    assert (out / "results.yml").read_text() == first
    evaluate.main([*EVAL, "--out", str(out), "--seed", "7", "--force"])
    assert yaml.safe_load((out / "results.yml").read_text())["seed"] == 7
    # the default directory is keyed by the model run (or the policy)
    monkeypatch.chdir(tmp_path)
    evaluate.main(["--model", "SoftHandTranslate-v0", "--n-episodes", "1", "--no-plots"])
    evaluate.main([*EVAL])
    assert (tmp_path / "logs/eval/SoftHandTranslate-v0/ppo_SoftHandTranslate-v0_1_"
            "SoftHandTranslate-v0/results.yml").is_file()
    assert (tmp_path / "logs/eval/SoftHandReorient-v0/model-based/results.yml").is_file()


def test_goals_file_plays_the_given_goals_for_models_and_scripts(tmp_path):
    goals = [[0.002], [-0.003], 0.001]  # Translate: x in m (a bare number for a 1-D task)
    path = tmp_path / "goals.json"
    path.write_text(json.dumps(goals))
    for who in (["--model", "SoftHandTranslate-v0"],
                ["--policy", "model-based", "--env", "SoftHandTranslate-v0"]):
        out = tmp_path / who[1]
        summary = evaluate.main([*who, "--goals", str(path), "--no-plots", "--out", str(out)])
        eps = yaml.safe_load((out / "results.yml").read_text())["episodes"]
        assert [e["goal"] for e in eps] == [[0.002], [-0.003], [0.001]]  # exactly these
        assert summary["n_episodes"] == 3 and summary["success_rate"] == 1.0


@pytest.mark.parametrize(
    "content,fragment",
    [
        ("not json", "is not JSON"),
        ("[]", "JSON list of 1 .. 100000 goals"),
        ('{"goal": 1}', "JSON list"),
        ("[[0.001, 0.1]]", "each goal must be [x (m)]"),
        ('[["a"]]', "each goal must be [x (m)]"),
        ("[[NaN]]", "finite"),
        ("[[1e300]]", "outside the task's range"),
    ],
)
def test_goals_file_errors(tmp_path, capsys, content, fragment):
    path = tmp_path / "goals.json"
    path.write_text(content)
    _exit_2(capsys, evaluate.main, ["--policy", "model-based", "--env", "SoftHandTranslate-v0",
                                    "--goals", str(path), "--no-plots",
                                    "--out", str(tmp_path / "o")], fragment)


def test_soak_usage_errors_exit_2_and_a_failed_soak_1(capsys, monkeypatch):
    from softhand_env.tools import soak

    for argv, fragment in ((["--threads", "0"], "--threads must be in"),
                           (["--env-id", "Nope-v0"], "'Nope-v0' is not a soft-hand env"),
                           (["--num-envs", "0"], "--num-envs must be in"),
                           (["--steps", "x"], "invalid int value")):
        assert soak.main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err

    def failed(*args):  # one non-finite value: the soak fails
        return soak.SoakResult("SoftHandReorient-v0", 1, 10, 1.0, 10.0, 0, 0, nonfinite=1)

    monkeypatch.setattr(soak, "soak", failed)
    monkeypatch.setattr(soak, "format_result", lambda r: "failed")
    assert soak.main(["--steps", "10", "--num-envs", "1"]) == 1


def test_cli_keyword_values_are_read_with_bounds():
    """A YAML alias bomb or a 50,000-deep value in ``key:value`` items is refused in one line
    before it is expanded; plain values parse as YAML."""
    import time

    from agents.common.cli import UserError, parse_kv

    assert parse_kv(["x:0.5", "pair:[6, 6]", "flag:true"]) == {"x": 0.5, "pair": [6, 6],
                                                                  "flag": True}
    bomb = "{a: &a [x, x, x, x, x, x, x, x, x], " + ", ".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
        f"*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
        f"*{chr(97 + i)}]" for i in range(9)) + "}"
    for value in (bomb, "[" * 50_000 + "]" * 50_000):
        t0 = time.perf_counter()
        with pytest.raises(UserError) as err:
            parse_kv([f"hand_overrides:{value}"])
        assert time.perf_counter() - t0 < 5.0
        assert "\n" not in str(err.value) and len(str(err.value)) < 400


#: A 3 KB YAML "billion laughs": nine levels of nine aliases (9**9 nodes expanded).
BOMB = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 10))


@pytest.mark.parametrize("command", ["train", "distill"])
@pytest.mark.parametrize("text, fragment", [
    (BOMB + "SoftHandTranslate-v0: {policy: MlpPolicy, n_timesteps: 64, env_kwargs: "
     "{hand_overrides: *a9}}\n", "more than 100000 nodes (aliases)"),
    ("SoftHandTranslate-v0: " + "[" * 50_000 + "]" * 50_000 + "\n", "nested deeper than 32"),
    (".d: &d " + "[" * 20 + "]" * 20 + "\nSoftHandTranslate-v0: {policy: MlpPolicy, "
     "n_timesteps: 64, env_kwargs: {hand_overrides: " + "[" * 12 + "*d" + "]" * 12 + "}}\n",
     "nested deeper than 32"),  # deep only once the alias is expanded
    ("# padding\n" * 200_000, "larger than 1000000 bytes"),
    ("SoftHandTranslate-v0: {policy: MlpPolicy, n_timesteps: " + "9" * 5000 + "}\n",
     "integer longer than"),
])
def test_conf_file_is_read_with_the_bounds_of_model_configs(tmp_path, capsys, command, text,
                                                             fragment):
    """--conf-file (train and distill): size refused before parsing, depth (also through an
    alias), alias expansion and integer length bounded; one line, exit 2, fast, nothing
    written."""
    import time

    from agents import distill

    conf = tmp_path / "conf.yml"
    conf.write_text(text)
    argv = ["--env", "SoftHandTranslate-v0", "--conf-file", str(conf), "--log-folder",
            str(tmp_path / "logs")]
    if command == "distill":
        argv += ["--teacher", "SoftHandTranslate-v0"]
    t0 = time.perf_counter()
    _exit_2(capsys, distill.main if command == "distill" else train.main, argv, fragment)
    assert time.perf_counter() - t0 < 5.0
    assert not (tmp_path / "logs").exists()


def test_conf_file_anchors_and_merge_keys_within_the_bounds_are_read(tmp_path):
    """The zoo's anchors and merge keys (as in the shipped files) are read as before; the
    alias-expanded size counts each alias as its anchored node."""
    from agents.runs.hyperparams import load_hyperparams
    from softhand_env.physics.safe_yaml import MAX_EXPANDED_NODES, load_bounded

    conf = tmp_path / "conf.yml"
    conf.write_text(".base: &base {policy: MlpPolicy, n_timesteps: 64, env_kwargs: "
                    "{max_delta_deg: 0.5}}\nSoftHandTranslate-v0:\n  <<: *base\n  n_envs: 2\n")
    hp = load_hyperparams("ppo", "SoftHandTranslate-v0", str(conf))
    assert (hp["policy"], hp["n_envs"], hp["env_kwargs"]) == ("MlpPolicy", 2,
                                                             {"max_delta_deg": 0.5})
    side = int(MAX_EXPANDED_NODES ** 0.5) - 2  # a list of `side` aliases of `side` scalars
    just = f"a: &a [{', '.join(['0'] * side)}]\nb: [{', '.join(['*a'] * side)}]\n"
    assert len(load_bounded(just, aliases=True)["b"]) == side
    with pytest.raises(ValueError, match="aliases"):
        load_bounded(just.replace("b: [", "b: [*a, *a, *a, "), aliases=True)
    with pytest.raises(ValueError, match="aliases are not allowed"):
        load_bounded(just)  # model configs: no aliases at all


def test_node_count_bounds_only_documents_with_aliases(monkeypatch):
    """Without aliases the byte size bounds a document; the expanded-node bound is for the
    files that may use aliases."""
    from softhand_env.physics import safe_yaml

    monkeypatch.setattr(safe_yaml, "MAX_EXPANDED_NODES", 10)
    text = "[" + ", ".join(["1"] * 20) + "]"
    assert safe_yaml.load_bounded(text) == [1] * 20
    with pytest.raises(ValueError, match="more than 10 nodes"):
        safe_yaml.load_bounded(text, aliases=True)


@pytest.mark.filterwarnings("ignore:RK4 step dt:RuntimeWarning")  # the hand's stability warning
@pytest.mark.parametrize("command", ["train", "evaluate"])
def test_a_hand_whose_grasp_phase_fails_is_one_line_before_any_output(tmp_path, capsys,
                                                                      command):
    """``hand_overrides: {Kd: 1e6}`` given on purpose (train's --env-kwargs, evaluate's
    --task-kwargs): the grasp phase fails; PhysicsError as one line, exit 2, and no run
    directory or results (train tries the first reset before creating the run)."""
    over = "hand_overrides:{Kd: 1.0e+6}"
    if command == "train":
        _exit_2(capsys, train.main, TRAIN + ["--env-kwargs", over, "--log-folder",
                                             str(tmp_path / "logs")], "PhysicsError")
        assert not (tmp_path / "logs").exists()
    else:
        _exit_2(capsys, evaluate.main, ["--model", "SoftHandTranslate-v0", "--n-episodes", "1",
                                        "--task-kwargs", over, "--out", str(tmp_path / "o")],
                "PhysicsError")
        assert not (tmp_path / "o").exists()
