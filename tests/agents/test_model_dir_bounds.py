"""A model directory cannot exhaust the machine: every file is read within a size bound, YAML
without aliases and within a depth, zips by declared and streamed size, npz headers before any
allocation, networks counted before torch builds them; each refusal is one line, fast."""

from __future__ import annotations

import json
import shutil
import time
import zipfile

import gymnasium as gym
import numpy as np
import pytest

from agents import evaluate
from agents.common import cli
from agents.runs import loading
from agents.runs.model_files import MAX_DATA_BYTES, ModelFileError, check_network_size, sha256
from agents.runs.writing import reseal
from agents.runs.zoo_dialect import zoo_yaml_dump, zoo_yaml_load

SHIPPED = loading.shipped_models()
ENV = "SoftHandTranslate-v0"
#: Seconds a refusal may take (before any episode; most of it is importing torch).
FAST_S = 60.0
#: A 3 KB YAML "billion laughs": nine levels of nine aliases.
BOMB = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]\n" for i in range(1, 10))


def _copy(tmp_path):
    run = tmp_path / "run"
    shutil.copytree(SHIPPED[ENV].parent, run)
    return run


def _config_path(run):
    return run / ENV / "config.yml"


def _edit(run, edit):
    config = zoo_yaml_load(_config_path(run).read_text())
    edit(config)
    zoo_yaml_dump(config, _config_path(run))
    reseal(run)


def _reseal_file(run, relpath):
    config = zoo_yaml_load(_config_path(run).read_text())
    config["softhand"]["sha256"][relpath] = sha256(run / relpath)
    zoo_yaml_dump(config, _config_path(run))


def _refused(capsys, argv, fragment, limit=FAST_S):
    start = time.monotonic()
    with pytest.raises(SystemExit) as exc:
        cli.run_cli(evaluate.main, argv)
    elapsed = time.monotonic() - start
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1 and fragment in err, err
    assert len(err) < 1000 and elapsed < limit, (len(err), elapsed)


def _argv(run):
    return ["--model", str(run), "--n-episodes", "1", "--no-plots"]


@pytest.mark.parametrize("use", ["env_kwargs:\n  x_tolerance_mm: *a9\n",
                                 "env_kwargs:\n  hand_overrides: {*a9 : 1}\n"])
def test_alias_bomb_in_an_env_keyword_fails_fast(tmp_path, capsys, use):
    assert len(BOMB) < 3000
    run = _copy(tmp_path)
    _config_path(run).write_text(BOMB + use)
    _refused(capsys, _argv(run), "aliases are not allowed")


def test_alias_bomb_in_a_hand_yaml_fails_fast_in_gym_make(tmp_path):
    hand = tmp_path / "hand.yaml"
    hand.write_text(BOMB + "E_MPa: *a9\n")
    start = time.monotonic()
    with pytest.raises(ValueError, match="aliases are not allowed"):
        gym.make(ENV, hand=str(hand))
    assert time.monotonic() - start < 5.0


@pytest.mark.parametrize("text, fragment", [
    ("[" * 50_000 + "]" * 50_000, "nested deeper"),
    ("x: " + "9" * 5000 + "\n", "integer longer"),
    ("!!python/object/apply:collections.OrderedDict {a: 1}\n", "OrderedDict"),
    ("!!python/object/apply:collections.OrderedDict [[[a, 1, 2]]]\n", "OrderedDict"),
    ("!!python/object/apply:collections.OrderedDict [[[[a], 1]]]\n", "OrderedDict"),
    ("!!python/object/apply:collections.OrderedDict [1, 2]\n", "OrderedDict"),
    ("x: " + "y" * 2_000_000 + "\n", "larger than"),
])
def test_unreadable_configs_are_one_line(tmp_path, capsys, text, fragment):
    run = _copy(tmp_path)
    _config_path(run).write_text(text)
    _refused(capsys, _argv(run), fragment)


def test_deep_goals_json_is_one_line(tmp_path, capsys):
    goals = tmp_path / "goals.json"
    goals.write_text("[" * 50_000 + "]" * 50_000)
    _refused(capsys, ["--model", ENV, "--n-episodes", "1", "--no-plots", "--goals",
                      str(goals), "--out", str(tmp_path / "o")], "nested deeper")


def test_sha256_record_that_is_not_a_mapping_of_digests_is_one_line(tmp_path, capsys):
    run = _copy(tmp_path)
    for bad in ("SoftHandTranslate-v0.zip", {"SoftHandTranslate-v0.zip": 12}):
        config = zoo_yaml_load(_config_path(run).read_text())
        config["softhand"]["sha256"] = bad
        zoo_yaml_dump(config, _config_path(run))
        _refused(capsys, _argv(run), "sha256")


def test_network_size_is_counted_before_torch_builds_it(tmp_path, capsys):
    box = gym.spaces.Box(-1, 1, (9,))
    act = gym.spaces.Box(-1, 1, (2,))
    assert check_network_size({"pi": [128, 128], "vf": [128, 128]}, box, act) == (
        10 * 128 + 129 * 128 + 129 * 2 + 10 * 128 + 129 * 128 + 129)
    with pytest.raises(ModelFileError, match="parameters"):
        check_network_size([4000, 4000, 4000], box, act)
    run = _copy(tmp_path)
    _edit(run, lambda c: c.update({"policy_kwargs": "dict(net_arch=[6000, 6000, 6000])"}))
    _refused(capsys, _argv(run), "net_arch")


def _rewrite_zip(path, edit, extra=()):
    with zipfile.ZipFile(path) as src:
        items = [(n, src.read(n)) for n in src.namelist()]
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as dst:
        for name, data in items:
            dst.writestr(name, edit(name, data))
        for name, data in extra:
            dst.writestr(name, data)


def test_policy_kwargs_in_the_zip_never_override_the_config(tmp_path):
    run = _copy(tmp_path)
    zip_path = run / f"{ENV}.zip"

    def tiny_net(name, data):
        if name != "data":
            return data
        d = json.loads(data)
        d["policy_kwargs"] = {"net_arch": [3]}  # plain JSON, not a pickled entry
        return json.dumps(d).encode()

    _rewrite_zip(zip_path, tiny_net)
    _reseal_file(run, f"{ENV}.zip")
    reseal(run)
    policy = loading.ModelPolicy(run)
    assert policy.model.policy_kwargs["net_arch"] == {"pi": [128, 128], "vf": [128, 128]}


def test_zip_bomb_is_refused_by_its_declared_and_its_streamed_size(tmp_path, capsys):
    run = _copy(tmp_path)
    zip_path = run / f"{ENV}.zip"
    _rewrite_zip(zip_path, lambda n, d: d, extra=[("padding", b"\0" * (MAX_DATA_BYTES * 40))])
    assert zip_path.stat().st_size < 2_000_000  # a small file that inflates to 320 MiB
    _reseal_file(run, f"{ENV}.zip")
    _refused(capsys, _argv(run), "padding")
    # a member whose directory entry understates its size: caught while streaming
    run2 = _copy(tmp_path / "b")
    zip2 = run2 / f"{ENV}.zip"
    _rewrite_zip(zip2, lambda n, d: d + b" " * (MAX_DATA_BYTES * 2) if n == "data" else d)
    raw = bytearray(zip2.read_bytes())
    with zipfile.ZipFile(zip2) as z:
        info = z.getinfo("data")
    size = info.file_size.to_bytes(4, "little")
    small = (1000).to_bytes(4, "little")
    # the central directory (and local header) entries hold the size: understate them
    raw = bytearray(bytes(raw).replace(size, small))
    zip2.write_bytes(bytes(raw))
    _reseal_file(run2, f"{ENV}.zip")
    _refused(capsys, _argv(run2), "cannot load model")


def _npz(run):
    return run / ENV / "vecnormalize.npz"


def test_forged_npz_header_is_refused_before_allocation(tmp_path, capsys):
    import io

    run = _copy(tmp_path)
    with np.load(_npz(run)) as data:
        arrays = {k: data[k] for k in data.files}
    forged = io.BytesIO()  # an .npy header declaring 1e11 float64, and 64 bytes of data
    np.lib.format.write_array_header_1_0(
        forged, {"descr": "<f8", "fortran_order": False, "shape": (100_000_000_000,)})
    with zipfile.ZipFile(_npz(run), "w") as z:
        for k, v in arrays.items():
            member = io.BytesIO()
            np.save(member, v)
            z.writestr(f"{k}.npy", forged.getvalue() + b"\0" * 64 if k == "obs_mean"
                       else member.getvalue())
    _reseal_file(run, f"{ENV}/vecnormalize.npz")
    _refused(capsys, _argv(run), "elements")


@pytest.mark.parametrize("epsilon", [5e-324, 0.0])
def test_npz_statistics_with_zero_variance_and_tiny_epsilon_are_refused(tmp_path, capsys,
                                                                        epsilon):
    run = _copy(tmp_path)
    with np.load(_npz(run)) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["obs_var"] = np.zeros_like(arrays["obs_var"])
    arrays["epsilon"] = np.float64(epsilon)
    with _npz(run).open("wb") as fh:
        np.savez(fh, **arrays)
    _reseal_file(run, f"{ENV}/vecnormalize.npz")
    _refused(capsys, _argv(run), "epsilon must be in")
