"""Sphinx extension: environment pages generated from the environments' own metadata.

Directives (for MyST pages; their output is Markdown parsed in place):

``softhand-env-spec``  ids...
    the registered spec of each id, read from ``gymnasium.registry`` after ``import
    softhand_env``: entry points, ``max_episode_steps``, ``reward_threshold`` and the registered
    keyword arguments.
``softhand-env-task``  task
    the task's defaults as :func:`softhand_env.envs.task_configs.load_task_config` loads them.
``softhand-env-manual``  section
    one ``## <section>`` of the ``SoftHandEnv`` docstring (the env's manual), without its
    heading.
``softhand-env-arguments``
    the keyword table: ``softhand_env.envs.options.arguments_table()`` where that function
    exists, else the docstring's ``## Arguments`` section.

The ``SoftHandEnv`` docstring is Markdown (Gymnasium's env-page shape). For the API reference,
:func:`markdown_docstring` hands it to MyST instead of the reStructuredText parser, its
``## `` headings as rubrics (a class body cannot hold sections).

Cross-references to this project's own names fail loudly (:func:`own_reference`): Sphinx
turns an unresolved ``{py:...}`` / ``:py:...:`` reference into plain text unless it runs
nitpicky, and nitpicky would report every NumPy shape word of the numpy-style type fields.
A reference to ``softhand_env.<...>`` or ``agents.<...>`` that Sphinx does not find is looked
up by import: a re-exported name (``softhand_env.physics.PhysicsError``) is sent to the page
of the object's defining module, a name that imports to nothing or to an object without an
entry in the API reference is a warning (an error under ``-W``).
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
import re
import sys
import types
from pathlib import Path
from typing import Any

from docutils import nodes
from sphinx.addnodes import pending_xref
from sphinx.application import Sphinx
from sphinx.environment import BuildEnvironment
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

LOGGER = logging.getLogger(__name__)

ROLE = re.compile(r":(?:py:)?(func|class|data|mod|meth|attr|exc|obj):`([^`]+)`")
HEADING = re.compile(r"^## (.+?)\s*$")


def myst_roles(text: str) -> str:
    """Rewrite reStructuredText roles (``:func:`x```) in MyST syntax (``{func}`x```)."""
    return ROLE.sub(lambda m: f"{{py:{m.group(1)}}}`{m.group(2)}`", text)


def manual() -> str:
    """The ``SoftHandEnv`` docstring, dedented."""
    from softhand_env.envs.softhand import SoftHandEnv

    return inspect.cleandoc(SoftHandEnv.__doc__ or "")


def manual_sections(text: str) -> dict[str, str]:
    """``## <title>`` sections of a Markdown docstring: title -> body (the text before the
    first heading under the key ``""``)."""
    sections: dict[str, list[str]] = {"": []}
    current = ""
    for line in text.splitlines():
        m = HEADING.match(line)
        if m:
            current = m.group(1)
            sections[current] = []
        else:
            sections[current].append(line)
    return {k: "\n".join(v).strip() + "\n" for k, v in sections.items()}


def manual_section(title: str) -> str:
    """One section of the env manual; KeyError naming the sections if there is none."""
    sections = manual_sections(manual())
    for key, body in sections.items():
        if key.lower() == title.lower():
            return body
    raise KeyError(f"SoftHandEnv docstring has no section {title!r}; it has {list(sections)}")


def arguments_markdown() -> str:
    """The keyword table: from the options record if it renders one, else from the manual."""
    try:
        from softhand_env.envs import options
    except ImportError:  # pragma: no cover - the module exists today
        options = None  # type: ignore[assignment]
    render = getattr(options, "arguments_table", None)
    if callable(render):
        table = render()
        if isinstance(table, str) and table.strip():
            return table
    return manual_section("Arguments")


def _code(value: Any) -> str:
    return f"`{value!r}`"


def spec_markdown(env_ids: list[str]) -> str:
    """A table of the registered specs of ``env_ids`` (``import softhand_env`` registers)."""
    import gymnasium as gym

    import softhand_env  # noqa: F401  (registers the ids)

    rows = ["| | " + " | ".join(f"`{i}`" for i in env_ids) + " |",
            "|---|" + "---|" * len(env_ids)]
    specs = [gym.spec(i) for i in env_ids]
    fields = [
        ("entry point", lambda s: f"`{s.entry_point}`"),
        ("vector entry point", lambda s: f"`{s.vector_entry_point}`"),
        ("max_episode_steps", lambda s: _code(s.max_episode_steps)),
        ("reward_threshold", lambda s: _code(s.reward_threshold)),
    ]
    for name, get in fields:
        rows.append(f"| {name} | " + " | ".join(get(s) for s in specs) + " |")
    keys = list(dict.fromkeys(k for s in specs for k in s.kwargs))
    for key in keys:
        cells = [_code(s.kwargs[key]) if key in s.kwargs else "–" for s in specs]
        rows.append(f"| kwargs `{key}` | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def task_markdown(task: str) -> str:
    """The defaults of ``configs/tasks/<task>.yaml`` as loaded, one row per keyword."""
    from softhand_env.envs.task_configs import load_task_config

    config = load_task_config(task)
    rows = ["| keyword | default |", "|---|---|"]
    rows += [f"| `{k}` | {_code(v)} |" for k, v in config.items()]
    return "\n".join(rows) + "\n"


class _MarkdownDirective(SphinxDirective):
    """Parse generated Markdown in place (the page must be a MyST page)."""

    def markdown(self) -> str:
        raise NotImplementedError

    def run(self) -> list[nodes.Node]:
        text = myst_roles(self.markdown())
        container = nodes.container()
        self.state.nested_parse(text.splitlines(), self.content_offset, container)
        return container.children


class EnvSpec(_MarkdownDirective):
    required_arguments = 1
    optional_arguments = 20

    def markdown(self) -> str:
        return spec_markdown(list(self.arguments))


class EnvTask(_MarkdownDirective):
    required_arguments = 1

    def markdown(self) -> str:
        return task_markdown(self.arguments[0])


class EnvManual(_MarkdownDirective):
    required_arguments = 1
    final_argument_whitespace = True

    def markdown(self) -> str:
        return manual_section(self.arguments[0])


class EnvArguments(_MarkdownDirective):
    def markdown(self) -> str:
        return arguments_markdown()


def markdown_docstring(app: Sphinx, what: str, name: str, obj: Any, options: Any,
                       lines: list[str]) -> None:
    """autodoc hook: a docstring written in Markdown (``## `` headings and pipe tables) is
    parsed by MyST (through a generated file under ``_autosummary/_markdown``)."""
    text = "\n".join(lines)
    if not (re.search(r"^## \S", text, flags=re.M) and re.search(r"^\|.*\|$", text, re.M)):
        return
    body = "\n".join(HEADING.sub(lambda m: f"```{{rubric}} {m.group(1)}\n```", ln)
                     for ln in text.splitlines())
    folder = Path(app.srcdir) / "_autosummary" / "_markdown"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.{hashlib.sha1(body.encode()).hexdigest()[:8]}.md.txt"
    if not path.exists():
        path.write_text(myst_roles(body))
    rel = path.relative_to(app.srcdir).as_posix()
    lines[:] = [f".. include:: /{rel}", "   :parser: myst_parser.sphinx_", ""]


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("softhand-env-spec", EnvSpec)
    app.add_directive("softhand-env-task", EnvTask)
    app.add_directive("softhand-env-manual", EnvManual)
    app.add_directive("softhand-env-arguments", EnvArguments)
    app.connect("autodoc-process-docstring", markdown_docstring, priority=300)
    # before napoleon and sphinx-autodoc-typehints (500), which parse the text themselves
    app.connect("autodoc-process-docstring", rst_repairs, priority=400)
    app.connect("missing-reference", own_reference)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}


# --- reStructuredText repairs of docstrings written as plain text ---------------------------

BORDER = re.compile(r"^(\s*)=+(?: +=+)+\s*$")
UNDERLINE = re.compile(r"^(\s*)([-=~^\"'`#*+])\2{2,}\s*$")
LITERAL = re.compile(r"(``.+?``|`[^`]+`_?)")


def escape_bars(line: str) -> str:
    """``|x - x*|`` in prose is an absolute value, not a substitution: escape its bars, outside
    inline literals and roles."""
    parts = LITERAL.split(line)
    return "".join(p if i % 2 else p.replace("|", "\\|") for i, p in enumerate(parts))


def _cells(line: str, starts: list[int]) -> tuple[list[str], bool]:
    """Split a simple-table row at the column starts; a cell whose text runs into the next
    column's margin pushes that boundary to the end of its word. Returns (cells, moved)."""
    bounds = list(starts)
    moved = False
    for j in range(1, len(bounds)):
        b = max(bounds[j], bounds[j - 1] + 1)
        while b < len(line) and line[b - 1] != " ":
            b += 1
        moved |= b != bounds[j]
        bounds[j] = b
    bounds.append(max(len(line), bounds[-1]))
    return [line[bounds[j]:bounds[j + 1]].strip() for j in range(len(starts))], moved


def widen_simple_tables(lines: list[str]) -> list[str]:
    """Rebuild simple tables whose text runs into a column margin (docutils: "Malformed
    table"), with every column as wide as its widest cell."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = BORDER.match(lines[i])
        if not m:
            out.append(lines[i])
            i += 1
            continue
        indent = m.group(1)
        border = lines[i][len(indent):].rstrip()
        starts = [k for k, ch in enumerate(border)
                  if ch == "=" and (k == 0 or border[k - 1] == " ")]
        j, borders = i + 1, [i]
        while j < len(lines) and len(borders) < 3:
            if BORDER.match(lines[j]):
                borders.append(j)
            elif not lines[j].strip() and len(borders) == 2:
                break
            j += 1
        end = borders[-1]
        rows, moved = [], False
        for k in range(i, end + 1):
            if k in borders:
                rows.append(None)
                continue
            cells, mv = _cells(lines[k][len(indent):], starts)
            moved |= mv
            rows.append(cells)
        if not moved:
            out.extend(lines[i:end + 1])
        else:
            widths = [max(len(seg), *(len(r[c]) for r in rows if r is not None))
                      for c, seg in enumerate(border.split())]
            for r in rows:
                if r is None:
                    out.append(indent + "  ".join("=" * w for w in widths))
                else:
                    cells = (c.ljust(w) for c, w in zip(r, widths, strict=True))
                    out.append(indent + "  ".join(cells).rstrip())
        i = end + 1
    return out


PIPE_ROW = re.compile(r"^(\s*)\|(.*)\|\s*$")
PIPE_RULE = re.compile(r"^\s*\|(?:\s*:?-+:?\s*\|)+\s*$")
MD_CODE = re.compile(r"(?<![`\w:])`([^`]+)`(?![`_\w])")


def _pipe_cells(row: str) -> list[str]:
    """The cells of a Markdown table row (inner text between the outer bars; ``\\|`` is a bar
    inside a cell)."""
    cells = re.split(r"(?<!\\)\|", row)
    return [c.strip().replace("\\|", "|") for c in cells]


def pipe_tables_to_list_tables(lines: list[str]) -> list[str]:
    """A Markdown pipe table (header row, ``|---|`` rule, rows) in a reStructuredText
    docstring becomes a ``list-table`` directive at the same indent, its Markdown code spans
    inline literals and its other bars escaped (docutils would read the rows as a line block;
    the directive's content is not repaired again). Such tables are what
    :func:`softhand_env.envs.options.arguments_table` puts into the vector env's docstring,
    under the ``**kwargs`` entry of its Parameters."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        head = PIPE_ROW.match(lines[i])
        if not (head and i + 1 < len(lines) and PIPE_RULE.match(lines[i + 1])):
            out.append(lines[i])
            i += 1
            continue
        indent = head.group(1)
        rows = [_pipe_cells(head.group(2))]
        j = i + 2
        while j < len(lines):
            m = PIPE_ROW.match(lines[j])
            if not m or m.group(1) != indent:
                break
            rows.append(_pipe_cells(m.group(2)))
            j += 1
        width = len(rows[0])
        if any(len(r) != width for r in rows):  # not a table this converter understands
            out.extend(lines[i:j])
            i = j
            continue
        # a table introduced by a deeper-indented line ending in ":" belongs to that line's
        # block (a field description): a table substituted into a docstring at a fixed indent
        # would otherwise end the section it is meant to sit in
        before = next((ln for ln in reversed(out) if ln.strip()), "")
        if before.rstrip().endswith(":") and len(before) - len(before.lstrip()) > len(indent):
            indent = before[: len(before) - len(before.lstrip())]
        out += [f"{indent}.. list-table::", f"{indent}   :header-rows: 1", ""]
        for row in rows:
            for k, cell in enumerate(row):
                text = escape_bars(MD_CODE.sub(r"``\1``", cell))
                out.append(f"{indent}   {'* -' if k == 0 else '  -'} {text}".rstrip())
        if j < len(lines) and lines[j].strip():
            out.append("")
        i = j
    return out


BROKEN_ROLE = re.compile(r"(:[a-z:]+:`[^`\s]*)$")


def join_broken_roles(lines: list[str]) -> list[str]:
    """A role whose target is wrapped onto the next line (``:func:`~a.b.`` / ``c```) is joined
    (autosummary cuts a one-line summary at the first ". ", which would split it)."""
    out: list[str] = []
    for line in lines:
        if out and BROKEN_ROLE.search(out[-1]) and line.strip():
            words = line.strip().split(maxsplit=1)
            head, rest = words[0], words[1] if len(words) > 1 else ""
            out[-1] = out[-1] + head
            if rest:
                out.append(line[: len(line) - len(line.lstrip())] + rest)
            continue
        out.append(line)
    return out


def rst_repairs(app: Sphinx, what: str, name: str, obj: Any, options: Any,
                lines: list[str]) -> None:
    """autodoc hook: make plain-text docstrings valid reStructuredText without changing what
    they say: absolute-value bars escaped, simple tables widened to their text, Markdown pipe
    tables as list tables, section underlines lengthened to their titles. Literal blocks
    (after ``::``) stay as written."""
    if lines and lines[0].startswith(".. include::"):
        return  # a Markdown docstring, parsed by MyST
    fixed = widen_simple_tables(pipe_tables_to_list_tables(join_broken_roles(lines)))
    literal_indent: int | None = None
    for k, line in enumerate(fixed):
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None:
            if line.strip() and indent <= literal_indent:
                literal_indent = None
            else:
                continue
        stripped = line.strip()
        if stripped.endswith("::"):
            literal_indent = indent
        if stripped.startswith(("| ", "+-", "+=", ">>>")) or stripped == "|":
            continue
        fixed[k] = escape_bars(line)
        if k + 1 < len(fixed) and stripped and (k == 0 or not fixed[k - 1].strip()):
            u = UNDERLINE.match(fixed[k + 1])
            if u and len(fixed[k + 1].strip()) < len(stripped) and u.group(1) == line[:indent]:
                fixed[k + 1] = u.group(1) + u.group(2) * len(stripped)
    lines[:] = fixed


# --- references to this project's own names ------------------------------------------------

OWN_PACKAGES = ("softhand_env", "agents")


def _is_own(name: str) -> bool:
    return name.split(".")[0] in OWN_PACKAGES


def locate(name: str) -> tuple[Any, str] | None:
    """Import ``name`` (a dotted path: the longest importable module prefix, then attributes)
    and return (object, canonical dotted name), or None if it names nothing. The canonical
    name is where the object is defined (``__module__`` + ``__qualname__`` of a class or
    function, a module's ``__name__``), with any remaining attribute path appended."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        except Exception:  # noqa: BLE001 - a module that fails to import names nothing here
            return None
        canonical = obj.__name__
        for part in parts[i:]:
            try:
                obj = getattr(obj, part)
            except AttributeError:
                return None
            qual = getattr(obj, "__qualname__", None)
            module = getattr(obj, "__module__", None)
            if (isinstance(obj, type | types.FunctionType) and isinstance(qual, str)
                    and isinstance(module, str) and "<locals>" not in qual):
                canonical = f"{module}.{qual}"
            else:
                canonical = f"{canonical}.{part}"
        return obj, canonical
    return None


def deprecated_alias(name: str) -> str | None:
    """The module of dotted ``name`` that is a deprecated alias (its docstring opens with
    "Deprecated alias", as ``softhand_env.tools.simulate``'s does), or None."""
    parts = name.split(".")
    for i in range(1, len(parts) + 1):
        module = sys.modules.get(".".join(parts[:i]))
        if module is not None and (module.__doc__ or "").startswith("Deprecated alias"):
            return module.__name__
    return None


def own_reference(app: Sphinx, env: BuildEnvironment, node: pending_xref,
                  contnode: nodes.TextElement) -> nodes.Element | None:
    """``missing-reference`` hook: a Python reference Sphinx did not resolve.

    * A target in this project (``softhand_env.``/``agents.``, or a short name that the
      current module imports from this project) is resolved at the object's defining module
      when that differs from the name written (re-exports, package shortcuts).
    * A ``softhand_env.``/``agents.`` target that still does not resolve is a warning: it
      names nothing (stale or misspelt) or an object the API reference does not document.
      So is a link through a deprecated alias module (it resolves, but should name the
      module the alias points to).
      Private names (a part starting with ``_``) are not documented by design and stay text.
    * Other targets (NumPy, Gymnasium, SB3, the shape words of numpy-style type fields) are
      left to Sphinx, which renders them as text.
    """
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    typ = node.get("reftype", "obj")
    explicit = _is_own(target)
    if explicit:
        candidates = [target]
    else:
        module = node.get("py:module") or ""
        if not _is_own(module) or not target or target.startswith("."):
            return None
        cls = node.get("py:class")
        candidates = ([f"{module}.{cls}.{target}"] if cls else []) + [f"{module}.{target}"]
    domain = env.get_domain("py")
    canonical = None
    for candidate in candidates:
        found = locate(candidate)
        if found is None:
            continue
        canonical = found[1]
        if not _is_own(canonical):
            return None  # a third-party object imported into our module
        if any(p.startswith("_") and not p.startswith("__") for p in canonical.split(".")):
            return None
        alias = deprecated_alias(target) if explicit else None
        if alias is not None:
            LOGGER.warning("py:%s reference %s goes through the deprecated alias %s: name %s",
                           typ, target, alias, canonical, location=node, type="softhand_docs",
                           subtype="own_reference")
            return None
        if canonical != target:
            xref = pending_xref("", refdomain="py", reftype=typ, reftarget=canonical,
                                refexplicit=node.get("refexplicit", False), refwarn=False)
            resolved = domain.resolve_xref(env, node["refdoc"], app.builder, typ, canonical,
                                           xref, contnode)
            if resolved is None and typ != "obj":  # e.g. :class: on a documented function
                resolved = domain.resolve_xref(env, node["refdoc"], app.builder, "obj",
                                               canonical, xref, contnode)
            if resolved is not None:
                return resolved
        break
    if explicit:
        where = f" (defined as {canonical})" if canonical and canonical != target else ""
        why = ("names no importable object" if canonical is None
               else "has no entry in the API reference")
        LOGGER.warning("py:%s reference %s%s %s", typ, target, where, why, location=node,
                       type="softhand_docs", subtype="own_reference")
    return None
