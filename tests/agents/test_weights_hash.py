"""The weights hash of a model zip (agents.runs.model_files.weights_sha256) and the shipped
-v1 models: their ids resolve to their own runs, whose records carry the weights hash."""

from __future__ import annotations

import io
import time
import zipfile

import pytest
import torch

from agents.runs import loading
from agents.runs.layout import MODELS_DIR
from agents.runs.model_files import ModelFileError, sha256, weights_sha256
from agents.runs.zoo_dialect import zoo_yaml_load

SHIPPED = loading.shipped_models()


def _rezip(src, dst, edit_policy=None):
    """Copy the zip at ``src`` to ``dst`` with new timestamps (and ``edit_policy(state)``)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "policy.pth" and edit_policy is not None:
                state = torch.load(io.BytesIO(data), weights_only=True)
                edit_policy(state)
                buf = io.BytesIO()
                torch.save(state, buf)
                data = buf.getvalue()
            stamp = time.localtime(time.time() + 86400)[:6]
            zout.writestr(zipfile.ZipInfo(info.filename, date_time=stamp), data)


def test_weights_hash_ignores_timestamps_and_sees_a_changed_weight(tmp_path):
    src = SHIPPED["SoftHandTranslate-v0"]
    same, changed = tmp_path / "same.zip", tmp_path / "changed.zip"
    _rezip(src, same)
    assert sha256(same) != sha256(src)  # the zip's bytes differ (timestamps)
    assert weights_sha256(same) == weights_sha256(src)

    def nudge(state):
        name = sorted(state)[0]
        state[name].view(-1)[0] += 1e-6

    _rezip(src, changed, nudge)
    assert weights_sha256(changed) != weights_sha256(src)


def test_weights_hash_of_a_zip_without_policy_is_refused(tmp_path):
    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("data", "{}")
    with pytest.raises(ModelFileError, match="policy.pth"):
        weights_sha256(bad)


@pytest.mark.parametrize("task", ["Translate", "Reorient"])
def test_v1_ids_resolve_to_their_own_runs_with_the_weights_hash(task):
    v0, v1 = f"SoftHand{task}-v0", f"SoftHand{task}-v1"
    assert SHIPPED[v0] == MODELS_DIR / "ppo" / f"{v0}_1" / f"{v0}.zip"
    assert SHIPPED[v1] == MODELS_DIR / "ppo" / f"{v1}_1" / f"{v1}.zip"
    run = loading.resolve_model(v1)
    assert run.zip_path == SHIPPED[v1]
    config = zoo_yaml_load((SHIPPED[v1].parent / v1 / "config.yml").read_text())
    record = config["softhand"]
    assert record["env_id"] == v1 and record["env_signature"]["env_id"] == v1
    assert record["env_signature"]["sensor_model"] == "realistic"
    assert record["weights_sha256"] == {f"{v1}.zip": weights_sha256(SHIPPED[v1])}
    assert record["sha256"][f"{v1}.zip"] == sha256(SHIPPED[v1])
