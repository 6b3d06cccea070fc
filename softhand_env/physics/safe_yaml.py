"""YAML from files a user did not write, read with bounded time and memory.

:func:`load_bounded` parses with a given SafeLoader subclass and refuses, before anything is
built: a text longer than :data:`MAX_YAML_BYTES`, aliases and anchors (``&a`` / ``*a``: the
configs this package reads and writes never use them, and expanding them is how a few
kilobytes become gigabytes), nesting deeper than :data:`MAX_DEPTH`, and integers longer than
:data:`MAX_INT_DIGITS` digits. Every refusal, and every YAML error, is a ``ValueError`` whose
message is one bounded line naming ``source``.

Hyper-parameter files in RL Zoo's dialect share settings through anchors and merge keys
(``<<: *defaults``), so ``aliases=True`` allows them, bounded instead: the document as if
every alias were expanded (each alias counts the nodes and the nesting of its anchored node)
must have at most :data:`MAX_EXPANDED_NODES` nodes and :data:`MAX_DEPTH` levels; an alias
bomb (each level repeating the previous one) is refused after a few events.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

#: Longest YAML text read (bytes).
MAX_YAML_BYTES = 1_000_000
#: Deepest nesting of sequences and mappings.
MAX_DEPTH = 32
#: Longest integer (digits): longer ones are refused before Python's int() would raise.
MAX_INT_DIGITS = 4000  # below Python's own int-parsing limit (4300)

#: Most nodes (scalars, sequences, mappings) of a document with its aliases expanded.
MAX_EXPANDED_NODES = 100_000

_LONG_INT = re.compile(rf"[-+]?[0-9_]{{{MAX_INT_DIGITS + 1},}}")


def _line(event: yaml.Event) -> int:
    mark = event.start_mark
    return mark.line + 1 if mark is not None else 0


def _check_events(loader: yaml.SafeLoader, source: str, aliases: bool = False) -> None:
    depth = 0
    nodes = 0  # with every alias expanded
    anchored: dict[str, tuple[int, int]] = {}  # anchor -> (nodes, height) of its node
    # open collections: (anchor, nodes before it, height of its tallest child)
    open_: list[list[Any]] = []

    def add(size: int, height: int) -> None:
        nonlocal nodes
        nodes += size
        if aliases and nodes > MAX_EXPANDED_NODES:  # without aliases: the size bound
            raise ValueError(f"{source}: YAML expands to more than {MAX_EXPANDED_NODES} nodes "
                             "(aliases)")
        if depth + height > MAX_DEPTH:
            raise ValueError(f"{source}: YAML nested deeper than {MAX_DEPTH} levels")
        if open_:
            open_[-1][2] = max(open_[-1][2], height)

    while loader.check_event():
        event = loader.get_event()
        anchor = getattr(event, "anchor", None)
        if not aliases and (isinstance(event, yaml.AliasEvent) or anchor is not None):
            raise ValueError(f"{source}: YAML anchors and aliases are not allowed (line "
                             f"{_line(event)})")
        if isinstance(event, yaml.AliasEvent):
            size, height = anchored.get(str(anchor), (1, 0))  # an unknown one: YAML error
            add(size, height)
        elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                raise ValueError(f"{source}: YAML nested deeper than {MAX_DEPTH} levels")
            open_.append([anchor, nodes, 0])
            nodes += 1
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            name, before, tallest = open_.pop()
            depth -= 1
            if name is not None:
                anchored[name] = (nodes - before, 1 + tallest)
            if open_:
                open_[-1][2] = max(open_[-1][2], 1 + tallest)
        elif isinstance(event, yaml.ScalarEvent):
            if event.style is None and _LONG_INT.fullmatch(event.value):
                raise ValueError(f"{source}: integer longer than {MAX_INT_DIGITS} digits (line "
                                 f"{_line(event)})")
            add(1, 0)
            if anchor is not None:
                anchored[anchor] = (1, 0)


def load_bounded(text: str | bytes, loader_cls: type = yaml.SafeLoader,
                 source: str = "YAML", aliases: bool = False) -> Any:
    """``yaml.load(text, Loader=loader_cls)`` (a SafeLoader subclass) with the limits of the
    module doc checked first; ``ValueError`` (one line, naming ``source``) otherwise.
    ``aliases``: allow anchors and aliases within the expanded-size bounds (module doc)."""
    if len(text) > MAX_YAML_BYTES:
        raise ValueError(f"{source}: larger than {MAX_YAML_BYTES} bytes")
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{source}: not UTF-8 text") from None
    try:
        _check_events(loader_cls(text), source, aliases)  # a first pass over the events only
        return yaml.load(text, Loader=loader_cls)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        msg = " ".join(str(exc).split())[:300]
        raise ValueError(f"{source}: not valid YAML ({msg})") from None
    except (RecursionError, MemoryError, OverflowError) as exc:
        raise ValueError(f"{source}: not readable ({type(exc).__name__})") from None


def read_bounded(path: Any, source: str | None = None) -> str:
    """Text of the file ``path``, refused (``ValueError``) beyond :data:`MAX_YAML_BYTES`
    without reading more than that."""
    from pathlib import Path

    p = Path(path)
    name = source or str(p)
    try:
        with p.open("rb") as fh:
            data = fh.read(MAX_YAML_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"{name}: cannot read ({exc.strerror})") from None
    if len(data) > MAX_YAML_BYTES:
        raise ValueError(f"{name}: larger than {MAX_YAML_BYTES} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{name}: not UTF-8 text") from None
