"""Published names keep working after the move: the dotted wrapper paths that run configs name,
every shipped model, and the deprecated module aliases of softhand_env (which warn)."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest
import yaml

from agents.common.env_factory import wrapper_list
from agents.runs.hyperparams import CONFIG_DIR
from agents.runs.layout import CONFIG_FILE, MODELS_DIR
from agents.runs.loading import ModelPolicy, shipped_models
from agents.runs.zoo_dialect import zoo_yaml_load

#: Published dotted path -> the class's home.
PUBLISHED = {
    "agents.time_feature.TimeFeature": "agents.wrappers.time_feature.TimeFeature",
    "agents.time_feature.VecTimeFeature": "agents.wrappers.time_feature.VecTimeFeature",
    "agents.action_history.ActionHistory": "agents.wrappers.action_history.ActionHistory",
    "agents.action_history.VecActionHistory":
        "agents.wrappers.action_history.VecActionHistory",
    "agents.residual.ResidualWrapper": "agents.wrappers.residual.ResidualWrapper",
    "agents.residual.LoopPlanPolicy": "agents.scripted.loop_plan.LoopPlanPolicy",
}


def _resolve(path: str) -> object:
    module, _, name = path.rpartition(".")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("old", sorted(PUBLISHED))
def test_published_dotted_path_is_the_moved_class(old):
    assert _resolve(old) is _resolve(PUBLISHED[old])


def _wrapper_paths(spec) -> list[str]:
    items = spec if isinstance(spec, list) else [] if spec is None else [spec]
    return [next(iter(i)) if isinstance(i, dict) else i for i in items]


def test_every_wrapper_named_by_a_shipped_config_loads_through_the_allow_list():
    named = set()
    for conf in sorted(MODELS_DIR.glob(f"*/*/*/{CONFIG_FILE}")):
        named.update(_wrapper_paths(zoo_yaml_load(conf.read_text()).get("env_wrapper")))
    for conf in sorted(CONFIG_DIR.glob("*.yml")):
        for entry in yaml.safe_load(conf.read_text()).values():
            if isinstance(entry, dict):
                named.update(_wrapper_paths(entry.get("env_wrapper")))
    assert {"agents.time_feature.TimeFeature", "agents.action_history.ActionHistory",
            "agents.residual.ResidualWrapper"} <= named
    for path in sorted(named):
        ((cls, _),) = wrapper_list(path)
        assert cls is _resolve(PUBLISHED.get(path, path)), path
        # the class's new home passes the allow-list too
        ((moved, _),) = wrapper_list(f"{cls.__module__}.{cls.__name__}")
        assert moved is cls


def test_every_shipped_model_loads():
    runs = sorted(p.parent for p in MODELS_DIR.glob("*/*_*/*.zip"))
    shipped = shipped_models()
    assert runs and {p.parent for p in shipped.values()} == set(runs)
    for run in runs:
        policy = ModelPolicy(run)
        assert policy.path.parent == run and policy.model.observation_space is not None


@pytest.mark.parametrize("alias, target, name", [
    ("softhand_env.contact", "softhand_env.physics.contact", "contact_within_base"),
    ("softhand_env.bench", "softhand_env.tools.bench", "main"),
    ("softhand_env.bench_env", "softhand_env.tools.bench_env", "main"),
    ("softhand_env.tools.simulate", "softhand_env.physics.motions", "run_paper_motions"),
])
def test_deprecated_alias_warns_and_is_the_module_it_names(alias, target, name, monkeypatch):
    monkeypatch.delitem(sys.modules, alias, raising=False)
    with pytest.warns(DeprecationWarning, match=target.replace(".", r"\.")):
        module = importlib.import_module(alias)
    assert getattr(module, name) is getattr(importlib.import_module(target), name)
    monkeypatch.delitem(sys.modules, alias, raising=False)


def test_top_level_configs_link_both_homes():
    root = Path(__file__).resolve().parents[2] / "configs"
    assert (root / "agents").resolve() == CONFIG_DIR
    for name in ("hand", "tasks"):
        assert (root / name).resolve() == (root.parent / "softhand_env" / "configs" / name)
        assert list((root / name).glob("*.yaml"))
