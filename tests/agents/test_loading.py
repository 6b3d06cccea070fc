"""Loading a model directory runs no code from it: every attack on the files is refused (or
made harmless), one line, exit code 2, and the attacker's command never runs."""

from __future__ import annotations

import base64
import json
import os
import pickle
import shutil
import zipfile

import numpy as np
import pytest

from agents import evaluate
from agents.common import cli
from agents.runs import loading
from agents.runs.model_files import sha256
from agents.runs.normalization import ObsNormalizer
from agents.runs.zoo_dialect import parse_expression, zoo_yaml_dump, zoo_yaml_load

SHIPPED = loading.shipped_models()
ENV = "SoftHandTranslate-v0"


class Payload:
    """Pickles to a call of ``os.system`` that creates ``marker``."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _copy(tmp_path, env_id=ENV):
    run = tmp_path / "run"
    shutil.copytree(SHIPPED[env_id].parent, run)
    return run


def _config(run, env_id=ENV):
    return zoo_yaml_load((run / env_id / "config.yml").read_text())


def _write(run, config, env_id=ENV):
    zoo_yaml_dump(config, run / env_id / "config.yml")


def _reseal(run, relpath, env_id=ENV):
    """Record the current checksum of ``relpath`` (as an attacker who rewrites config.yml)."""
    config = _config(run, env_id)
    config["softhand"]["sha256"][relpath] = sha256(run / relpath)
    _write(run, config, env_id)


def _refused(capsys, run, fragment, *extra):
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(evaluate.main, ["--model", str(run), "--n-episodes", "1", "--no-plots",
                                    *extra])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err


def _rewrite_zip(path, edit):
    """Rewrite the SB3 zip at ``path``; ``edit(name, bytes) -> bytes``."""
    with zipfile.ZipFile(path) as src:
        items = [(n, src.read(n)) for n in src.namelist()]
    with zipfile.ZipFile(path, "w") as dst:
        for name, data in items:
            dst.writestr(name, edit(name, data))


def test_crafted_vecnormalize_pkl_is_never_unpickled(tmp_path, capsys):
    run, marker = _copy(tmp_path), tmp_path / "pwned"
    (run / ENV / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    summary = evaluate.main(["--model", str(run), "--n-episodes", "2", "--no-plots",
                             "--out", str(tmp_path / "out")])
    assert summary["success_rate"] == 1.0 and not marker.exists()  # read from the .npz
    (run / ENV / "vecnormalize.npz").unlink()  # only the pickle left: refused
    _refused(capsys, run, "vecnormalize.pkl does not match the checksum")
    _reseal(run, f"{ENV}/vecnormalize.pkl")  # even with a matching checksum
    _refused(capsys, run, "a pickle, which can run code")
    assert not marker.exists()


def test_npz_statistics_normalise_exactly_as_vecnormalize(tmp_path):
    run = SHIPPED[ENV].parent
    with open(run / ENV / "vecnormalize.pkl", "rb") as fh:
        vecnormalize = pickle.load(fh)  # our own shipped file
    norm = ObsNormalizer(run / ENV / "vecnormalize.npz", obs_dim=9)
    obs = np.random.default_rng(0).normal(0, 3, (50, 9)).astype(np.float32)
    np.testing.assert_array_equal(norm(obs), vecnormalize.normalize_obs(obs))
    bad = tmp_path / "bad.npz"
    np.savez(bad, obs_mean=np.array([object()], dtype=object))
    with pytest.raises(ValueError, match="bad.npz"):
        ObsNormalizer(bad)


@pytest.mark.parametrize("wrapper", ["pydoc.pipepager",
                                     [{"pydoc.pipepager": {"cmd": "touch {marker}"}}],
                                     "os.system", "agents.residual.LoopPlanPolicy"])
def test_env_wrapper_outside_the_allow_list_is_refused(tmp_path, capsys, wrapper):
    run, marker = _copy(tmp_path), tmp_path / "pwned"
    config = _config(run)
    config["env_wrapper"] = json.loads(json.dumps(wrapper).replace("{marker}", str(marker)))
    _write(run, config)
    _refused(capsys, run, "refused")
    assert not marker.exists()


def _serialized(obj):
    return {":type:": "<class 'x'>", ":serialized:": base64.b64encode(pickle.dumps(obj)).decode()}


def test_pickled_zip_entry_is_rebuilt_or_refused_unless_trusted(tmp_path, capsys):
    run, marker = _copy(tmp_path), tmp_path / "pwned"
    zip_path = run / f"{ENV}.zip"

    def poison_space(name, data):
        if name != "data":
            return data
        d = json.loads(data)
        d["observation_space"][":serialized:"] = _serialized(Payload(marker))[":serialized:"]
        return json.dumps(d).encode()

    _rewrite_zip(zip_path, poison_space)
    _refused(capsys, run, "does not match the checksum")  # altered file
    _reseal(run, f"{ENV}.zip")
    # a rebuildable entry: rebuilt from the env, the pickle is never read
    evaluate.main(["--model", str(run), "--n-episodes", "1", "--no-plots",
                   "--out", str(tmp_path / "o1")])
    assert not marker.exists()

    def add_entry(name, data):
        if name != "data":
            return data
        d = json.loads(data)
        d["sneaky"] = _serialized(Payload(marker))
        return json.dumps(d).encode()

    _rewrite_zip(zip_path, add_entry)
    _reseal(run, f"{ENV}.zip")
    _refused(capsys, run, "pickled entries sneaky cannot be rebuilt")
    assert not marker.exists()
    # --trust-model lets SB3 unpickle exactly such entries: the command runs
    evaluate.main(["--model", str(run), "--n-episodes", "1", "--no-plots", "--trust-model",
                   "--out", str(tmp_path / "o2")])
    assert marker.exists()


def test_weights_are_read_without_unpickling(tmp_path, capsys):
    run, marker = _copy(tmp_path), tmp_path / "pwned"
    _rewrite_zip(run / f"{ENV}.zip", lambda name, data: (
        pickle.dumps(Payload(marker)) if name == "policy.pth" else data))
    _reseal(run, f"{ENV}.zip")
    _refused(capsys, run, "cannot load model")
    assert not marker.exists()


def test_shipped_v0_model_is_refused_on_its_v1_id(capsys):
    # the shipped models were trained on the v0 ids (ideal sensing); they load for v0
    # (tests/test_agents_evaluate.py) and are refused on v1 in one line
    # (the run's env signature refuses it too: sensor_model, tests/test_reliability_signature.py)
    v1 = ENV.replace("-v0", "-v1")
    _refused(capsys, SHIPPED[ENV].parent, f"trained on {ENV}, not {v1}", "--env", v1)


def test_swapped_model_file_is_refused(tmp_path, capsys):
    run = _copy(tmp_path, "SoftHandReorient-v0")
    shutil.copy(SHIPPED[ENV], run / "SoftHandReorient-v0.zip")  # Translate weights, same shapes
    _refused(capsys, run, "SoftHandReorient-v0.zip does not match the checksum")


def test_config_with_python_tags_other_than_ordered_dict_is_refused(tmp_path, capsys):
    run, marker = _copy(tmp_path), tmp_path / "pwned"
    path = run / ENV / "config.yml"
    path.write_text(path.read_text() + f"  - - x\n    - !!python/object/apply:os.system "
                                       f"['touch {marker}']\n")
    _refused(capsys, run, "not readable as the zoo's YAML")
    assert not marker.exists()


@pytest.mark.parametrize("text", ["__import__('os').system('id')", "nn.Module",
                                  "dict(a=open('x'))", "os.system", "[x for x in ()]",
                                  "dict(**{'a': 1})", "nn.Tanh.__subclasses__"])
def test_zoo_expressions_outside_the_grammar_are_refused(text):
    with pytest.raises(ValueError):
        parse_expression(text)
