"""Every repository path and every ``python -m`` module the docs name exists.

Scanned: README.md, the Markdown pages under docs/ and the comments of the shipped configs
(``softhand_env/configs`` and ``agents/configs``; the top-level ``configs/`` links to them).
The ``results.yml`` and ``config.yml`` files of ``agents/models`` are written by the commands
and not scanned.

A *path mention* is, in Markdown, a backticked token with a ``/`` that either ends in a known
file extension or starts with one of the repository's top-level folders; in a YAML comment the
same kind of token without backticks. Tokens with placeholders (``<task>``, ``*``, ``$X``) are
patterns, not paths, and paths under the folders that ``.gitignore`` lists (``out/``,
``logs/``, ...) are outputs of the commands. Every other mention must exist relative to the
repository root. A *module mention* is ``python -m NAME`` (code blocks included): NAME must be
found on ``sys.path`` without running it (a package needs a ``__main__``). A *name mention*
is an inline code span of the Markdown that starts with a dotted name in ``softhand_env`` or
``agents`` (```agents.runs.layout.MODELS_DIR```, a ``{py:...}`` role's target), or what an
``import`` statement of a code block names (``from agents.runs.hyperparams import config_path``):
it must import (the longest module prefix, then attributes), so a renamed module or object
fails here.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXTENSIONS = (".py", ".md", ".yaml", ".yml", ".toml", ".png", ".npz", ".zip", ".pkl", ".json",
              ".csv", ".txt", ".gif", ".cfg", ".sh")
TOP_FOLDERS = tuple(sorted(p.name for p in ROOT.iterdir() if p.is_dir()
                           and (not p.name.startswith((".", "__")) or p.name == ".ci")))
BACKTICKED = re.compile(r"`([^`\s]+)`")
BARE = re.compile(r"(?<![\w./-])((?:[\w.-]+/)+[\w.-]*\w/?)")
MODULE = re.compile(r"\bpython3? -m ([A-Za-z_]\w*(?:\.\w+)*)(?![\w.<{])")
PLACEHOLDER = re.compile(r"[<>*${}\[\]]|\.\.\.|://")
CODE_SPAN = re.compile(r"`([^`\n]+)`")
OWN_NAME = re.compile(r"^((?:softhand_env|agents)(?:\.[A-Za-z_]\w*)+)")
FROM_IMPORT = re.compile(r"\bfrom ((?:softhand_env|agents)(?:\.\w+)*) import (\w+(?:, *\w+)*)")
IMPORT = re.compile(r"\bimport ((?:softhand_env|agents)(?:\.\w+)*)")


def ignored_roots() -> tuple[str, ...]:
    """Top-level output folders of the commands, as ``.gitignore`` names them (``out/``)."""
    lines = (ROOT / ".gitignore").read_text().splitlines()
    return tuple(ln.strip().strip("/") + "/" for ln in lines
                 if re.fullmatch(r"[\w.-]+/", ln.strip()))


def looks_like_path(token: str) -> bool:
    token = token.rstrip(".,;:)")
    if "/" not in token or PLACEHOLDER.search(token) or token.startswith(("/", "~")):
        return False
    if token.startswith(ignored_roots()):
        return False
    return token.endswith(EXTENSIONS) or token.split("/")[0] in TOP_FOLDERS


def path_mentions(text: str, *, backticked: bool = True) -> list[str]:
    """Repository paths named in ``text`` (backticked tokens, or bare tokens for YAML)."""
    tokens = BACKTICKED.findall(text) if backticked else BARE.findall(text)
    return [t.rstrip(".,;:)") for t in tokens if looks_like_path(t)]


def module_mentions(text: str) -> list[str]:
    return MODULE.findall(text)


def module_exists(name: str) -> bool:
    """``python -m name`` would find a module: each dotted part located on the path without
    importing (no package code runs); a package must have a ``__main__``."""
    parts = name.split(".")
    spec = importlib.util.find_spec(parts[0])
    for part in parts[1:]:
        if spec is None or not spec.submodule_search_locations:
            return False
        spec = importlib.machinery.PathFinder.find_spec(
            f"{spec.name}.{part}", list(spec.submodule_search_locations))
    if spec is None:
        return False
    if spec.submodule_search_locations:  # a package: python -m runs its __main__
        return importlib.machinery.PathFinder.find_spec(
            f"{spec.name}.__main__", list(spec.submodule_search_locations)) is not None
    return True


def name_mentions(text: str) -> list[str]:
    """Dotted names of this project that open an inline code span of Markdown ``text`` or
    that its ``import`` statements import."""
    spans = (OWN_NAME.match(s) for s in CODE_SPAN.findall(text))
    names = [m.group(1) for m in spans if m]
    names += [f"{m.group(1)}.{n.strip()}" for m in FROM_IMPORT.finditer(text)
              for n in m.group(2).split(",")]
    names += IMPORT.findall(text)
    return names


def name_exists(name: str) -> bool:
    """``name`` imports: its longest module prefix is found and imported (import errors of an
    existing module propagate), and the rest are attributes."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        module = ".".join(parts[:i])
        try:
            spec = importlib.util.find_spec(module)
        except ModuleNotFoundError:  # a parent is a module, not a package
            spec = None
        if spec is None:
            continue
        with warnings.catch_warnings():  # the pages name the deprecated aliases as such
            warnings.simplefilter("ignore", DeprecationWarning)
            obj = importlib.import_module(module)
        for part in parts[i:]:
            if not hasattr(obj, part):
                return False
            obj = getattr(obj, part)
        return True
    return False


def missing(text: str, *, yaml_comments: bool = False) -> list[str]:
    """The mentions of ``text`` that do not exist, as ``path: ...`` / ``module: ...``."""
    if yaml_comments:
        text = "\n".join(ln.split("#", 1)[1] for ln in text.splitlines() if "#" in ln)
    bad = [f"path: {p}" for p in path_mentions(text, backticked=not yaml_comments)
           if not (ROOT / p).exists()]
    bad += [f"module: {m}" for m in module_mentions(text) if not module_exists(m)]
    if not yaml_comments:
        bad += [f"name: {n}" for n in name_mentions(text) if not name_exists(n)]
    return bad


def markdown_files() -> list[Path]:
    pages = [p for p in (ROOT / "docs").rglob("*.md")
             if not {"_build", "_autosummary"} & set(p.relative_to(ROOT / "docs").parts)]
    return [ROOT / "README.md", *sorted(pages)]


def yaml_files() -> list[Path]:
    return sorted(p for ext in ("*.yaml", "*.yml")
                  for folder in (ROOT / "softhand_env" / "configs", ROOT / "agents" / "configs")
                  for p in folder.rglob(ext))


@pytest.mark.parametrize("path", markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_markdown_mentions_exist(path):
    assert missing(path.read_text()) == []


@pytest.mark.parametrize("path", yaml_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_yaml_comment_mentions_exist(path):
    assert missing(path.read_text(), yaml_comments=True) == []


def test_the_scan_sees_the_mentions_it_checks():
    """The checks above are not vacuous: the pages name paths and modules."""
    text = "\n".join(p.read_text() for p in markdown_files())
    paths, modules = set(path_mentions(text)), set(module_mentions(text))
    assert {"configs/hand/paper_ch5.yaml", "tests/envs/test_random.py"} <= paths
    assert {"agents.demo", "agents.train", "softhand_env.figures", "pytest"} <= modules
    assert {"softhand_env.physics.motions", "agents.runs.loading",
            "agents.scripted.policies.PaperSequencePolicy"} <= set(name_mentions(text))
    assert any(p.parts[-3:-1] == ("agents", "configs") for p in yaml_files())
    yaml_text = "\n".join(ln.split("#", 1)[1] for p in yaml_files()
                          for ln in p.read_text().splitlines() if "#" in ln)
    assert "softhand_env/physics/params.py" in path_mentions(yaml_text, backticked=False)


def test_a_wrong_mention_is_reported():
    text = ("The loader is `softhand_env/params.py`, the hand `configs/hand/paper.yaml`, see "
            "`docs/nowhere.md`; run `python -m agents.no_such_command` or python -m "
            "softhand_env.physics (a package without __main__). Fine: `configs/tasks/<task>.yaml`, "
            "`out/demo/summary.md`, `x/theta`, python -m agents.demo, `docs/design.md`. Names: "
            "`agents.loading.MODELS_DIR`, {py:func}`softhand_env.tools.simulate.run_paper_motion`"
            ", fine: `agents.runs.layout.MODELS_DIR`, {py:class}`softhand_env.physics.HandPhysics`"
            ", `agents.sb3.curriculum.set_goal_scale(venv, s)`, `agents.<name>`.\n"
            "    python -c \"from agents.hyperparams import config_path; import agents.loading\"\n"
            "    python -c \"from agents.runs.hyperparams import config_path; import agents\"\n")
    assert missing(text) == ["path: softhand_env/params.py", "path: configs/hand/paper.yaml",
                             "path: docs/nowhere.md", "module: agents.no_such_command",
                             "module: softhand_env.physics", "name: agents.loading.MODELS_DIR",
                             "name: softhand_env.tools.simulate.run_paper_motion",
                             "name: agents.hyperparams.config_path", "name: agents.loading"]
    comment = "key: 1.0   # see softhand_env/params.py and docs/design.md\n"
    assert missing(comment, yaml_comments=True) == ["path: softhand_env/params.py"]
