"""The import layering of docs/layout.md, read from the source with ``ast`` (nothing is run).

(a) nothing in ``softhand_env`` imports ``agents``; (b) the layers of ``softhand_env`` import
only downwards: physics <- quasistatic <- envs <- cli (the commands' entry point) <- tools /
figures (the package's face ``softhand_env/__init__`` registers the environments: it sits
with ``envs``; the top-level
modules ``play``, ``contact``, ``bench``, ``bench_env`` sit above every layer); (c) no import
cycle among the modules of ``agents`` (imports executed when a module is imported: module
level, ``TYPE_CHECKING`` blocks and function bodies left out); (d) a command (a top-level
``agents/<name>.py`` with a ``__main__`` block) uses no other command's internals: it may run
another command through its ``main`` (as ``agents.demo`` runs ``agents.evaluate``), nothing
else; the top level of ``agents`` holds commands and the published alias modules only.

Each rule is a function of an import graph; the ``*_flags_*`` tests feed each one a graph with
a deliberate violation, so a rule that could not fail would fail its own test.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Layer of each sub-package of softhand_env (lower imports nothing higher); siblings of one
#: rank do not import each other.
LAYERS = {"physics": 0, "quasistatic": 1, "envs": 2, "cli": 3, "tools": 4, "figures": 4}
#: Rank of the package's face (it imports the registered environments).
FACE_RANK = 2
#: Rank of the top-level modules of softhand_env (command, aliases): above every layer.
TOP_RANK = 5
#: Top-level modules of agents that are no commands: the published dotted paths of run
#: configs' ``env_wrapper`` entries.
AGENT_ALIASES = {"agents.time_feature", "agents.action_history", "agents.residual"}


@dataclass
class Module:
    """One module: its dotted name, every module it imports (anywhere), those it imports when
    it is imported (module level), whether it has a ``__main__`` block, and for each
    imported module the names it takes from it (``from m import a``) or the attributes it
    reads of it (``import m`` / ``from pkg import m``; ``"*"``: the module object itself is
    used otherwise)."""

    name: str
    imports: set[str] = field(default_factory=set)
    load_time: set[str] = field(default_factory=set)
    main: bool = False
    uses: dict[str, set[str]] = field(default_factory=dict)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _load_time_nodes(body: list[ast.stmt]) -> list[ast.stmt]:
    """Statements run when the module is imported (into if / try blocks, not into functions,
    classes' methods or ``if TYPE_CHECKING``)."""
    out: list[ast.stmt] = []
    for node in body:
        if isinstance(node, ast.If):
            if _is_type_checking(node):
                continue
            out += _load_time_nodes(node.body) + _load_time_nodes(node.orelse)
        elif isinstance(node, ast.Try):
            out += _load_time_nodes(node.body)
            for handler in node.handlers:
                out += _load_time_nodes(handler.body)
            out += _load_time_nodes(node.orelse) + _load_time_nodes(node.finalbody)
        elif isinstance(node, ast.ClassDef):
            out += [n for n in _load_time_nodes(node.body)
                    if not isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
        elif not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            out.append(node)
    return out


def parse_module(path: Path, known: set[str]) -> Module:
    """The imports of the file ``path``; ``known``: every module name of the tree (to tell
    ``from pkg import submodule`` from ``from module import name``)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), filename=str(path))
    mod = Module(name)
    bound: dict[str, str] = {}  # local name -> module it is bound to

    def targets(node: ast.stmt) -> list[tuple[str, str | None, str | None]]:
        """(imported module, name taken from it or None, local binding of a module)."""
        out: list[tuple[str, str | None, str | None]] = []
        if isinstance(node, ast.Import):
            for alias in node.names:
                out.append((alias.name, None, alias.asname))
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                if sub in known:  # from pkg import submodule
                    out.append((sub, None, alias.asname or alias.name))
                else:
                    out.append((base, alias.name, None))
        return out

    load_time = {id(n) for n in _load_time_nodes(tree.body)}
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for target, taken, binding in targets(node):
                mod.imports.add(target)
                if id(node) in load_time:
                    mod.load_time.add(target)
                used = mod.uses.setdefault(target, set())
                if taken is not None:
                    used.add(taken)
                elif binding is not None:
                    bound[binding] = target
                else:  # import a.b.c: the name a is bound, the module used through it
                    used.add("*")
        elif (isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
              and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__"):
            mod.main = True
    parents: dict[int, ast.AST] = {}
    for parent in ast.walk(tree):
        for child in ast.iter_child_nodes(parent):
            parents[id(child)] = parent
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id in bound:
            parent = parents.get(id(node))
            attr = parent.attr if isinstance(parent, ast.Attribute) else "*"
            mod.uses.setdefault(bound[node.id], set()).add(attr)
    return mod


def project_modules() -> dict[str, Module]:
    files = sorted([*(ROOT / "softhand_env").rglob("*.py"), *(ROOT / "agents").rglob("*.py")])
    known = {module_name(p) for p in files}
    return {module_name(p): parse_module(p, known) for p in files}


def _in(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


# ------------------------------------------------------------------------------- the rules
def env_imports_of_agents(modules: dict[str, Module]) -> list[str]:
    """(a) ``module -> agents...`` for every import of agents from softhand_env."""
    return sorted(f"{m.name} -> {t}" for m in modules.values() if _in(m.name, "softhand_env")
                  for t in m.imports if _in(t, "agents"))


def env_rank(name: str) -> tuple[int, str]:
    """Rank and layer of a softhand_env module (:data:`LAYERS`)."""
    parts = name.split(".")
    if len(parts) == 1:  # the face: with envs (it registers them; envs reads its version)
        return FACE_RANK, "envs"
    if parts[1] in LAYERS:
        return LAYERS[parts[1]], parts[1]
    return TOP_RANK, name


def upward_imports(modules: dict[str, Module]) -> list[str]:
    """(b) imports of softhand_env from a lower layer into a higher one, or between two
    layers of one rank."""
    bad = []
    for m in modules.values():
        if not _in(m.name, "softhand_env"):
            continue
        rank, layer = env_rank(m.name)
        for t in m.imports:
            if not _in(t, "softhand_env"):
                continue
            t_rank, t_layer = env_rank(t)
            if t_rank > rank or (t_rank == rank and t_layer != layer):
                bad.append(f"{m.name} ({layer}) -> {t} ({t_layer})")
    return sorted(bad)


def agent_cycles(modules: dict[str, Module]) -> list[list[str]]:
    """(c) the import cycles (strongly connected components of more than one module, or a
    module importing itself) among the agents modules, at import time."""
    graph = {n: sorted(t for t in m.load_time if t in modules and _in(t, "agents"))
             for n, m in modules.items() if _in(n, "agents")}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's algorithm
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph[v]:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def commands(modules: dict[str, Module]) -> set[str]:
    """Top-level agents modules with a ``__main__`` block."""
    return {n for n, m in modules.items() if n.count(".") == 1 and _in(n, "agents") and m.main}


def command_internals_used(modules: dict[str, Module]) -> list[str]:
    """(d) ``command -> other command: names`` for every use of another command beyond its
    ``main``."""
    cmds = commands(modules)
    bad = []
    for name in sorted(cmds):
        for target, used in modules[name].uses.items():
            if target in cmds and target != name and used - {"main"}:
                bad.append(f"{name} -> {target}: {', '.join(sorted(used - {'main'}))}")
    return bad


def stray_top_level(modules: dict[str, Module]) -> list[str]:
    """Top-level agents modules that are neither commands nor published aliases."""
    top = {n for n in modules if n.count(".") == 1 and _in(n, "agents")
           and not (ROOT / Path(*n.split("."))).is_dir()}
    return sorted(top - commands(modules) - AGENT_ALIASES)


# -------------------------------------------------------------------------------- the tree
@pytest.fixture(scope="module")
def modules() -> dict[str, Module]:
    return project_modules()


def test_the_tree_is_read(modules):
    # the parser sees the imports it must judge (a silent empty graph would pass every rule)
    assert {"agents.train", "agents.demo", "softhand_env.envs.softhand"} <= set(modules)
    assert "agents.sb3.training" in modules["agents.distill"].imports
    assert "agents.evaluate" in modules["agents.demo"].imports
    assert "softhand_env.physics.hand" in modules["softhand_env.envs.transition"].load_time
    assert {"train", "distill", "evaluate", "demo", "pose_figures", "learning_curves",
            "bench_train", "rllib_train", "collect", "bc", "recurrent_distill"} == {c.split(".")[1]
                                                            for c in commands(modules)}


def test_softhand_env_never_imports_agents(modules):
    assert env_imports_of_agents(modules) == []


def test_softhand_env_layers_import_only_downwards(modules):
    assert upward_imports(modules) == []


def test_no_import_cycle_inside_agents(modules):
    assert agent_cycles(modules) == []


def test_no_command_uses_another_commands_internals(modules):
    assert command_internals_used(modules) == []
    assert stray_top_level(modules) == []


# ---------------------------------------------------------------- each rule can fail
def _graph(**edges: list[str]) -> dict[str, Module]:
    """Modules named by the keywords (``__`` for ``.``) importing the listed modules at load
    time, with ``main`` blocks for ``agents.<name>`` names ending in ``_cmd``."""
    out = {}
    for key, targets in edges.items():
        name = key.replace("__", ".")
        m = Module(name, imports=set(targets), load_time=set(targets),
                   main=name.count(".") == 1 and name.endswith("_cmd"))
        for t in targets:
            m.uses[t] = {"main"} if t.endswith("_cmd") else {"*"}
        out[name] = m
    for m in list(out.values()):
        for t in m.imports:
            out.setdefault(t, Module(t, main=t.count(".") == 1 and t.endswith("_cmd")))
    return out


def test_rules_flag_a_deliberate_violation():
    assert env_imports_of_agents(_graph(softhand_env__envs__x=["agents.runs.loading"]))
    assert upward_imports(_graph(softhand_env__physics__hand=["softhand_env.envs.config"]))
    assert upward_imports(_graph(softhand_env__figures__a=["softhand_env.tools.bench"]))
    assert upward_imports(_graph(softhand_env__physics__a=["softhand_env"]))
    assert not upward_imports(_graph(softhand_env__envs__a=["softhand_env.physics.hand"]))
    assert agent_cycles(_graph(agents__a__x=["agents.a.y"], agents__a__y=["agents.b.z"],
                               agents__b__z=["agents.a.x"])) == [
        ["agents.a.x", "agents.a.y", "agents.b.z"]]
    assert not agent_cycles(_graph(agents__a__x=["agents.a.y"], agents__a__y=[]))
    runs_main = _graph(agents__demo_cmd=["agents.evaluate_cmd"])
    assert command_internals_used(runs_main) == []  # running another command's main
    runs_main["agents.demo_cmd"].uses["agents.evaluate_cmd"].add("build")
    assert command_internals_used(runs_main) == ["agents.demo_cmd -> agents.evaluate_cmd: build"]
