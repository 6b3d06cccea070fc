"""Entry point and input checks of the command-line tools: a wrong input is one line, exit 2.

Every command (``softhand_env.figures``, ``softhand_env.play``, ``softhand_env.tools.*`` and,
through :mod:`agents.common.cli`, the ``agents`` commands) runs its ``main`` in
:func:`run_cli`:

* an expected failure (:data:`EXPECTED`: a :class:`CliError`, a ``ValueError`` or
  ``TypeError`` of a constructor, :class:`~softhand_env.physics.hand.PhysicsError`, YAML and
  JSON errors, ``RecursionError``, ``MemoryError``, ``OSError``, Gymnasium's errors such as
  ``DependencyNotInstalled``) is printed as ONE line ``error: <message>`` on stderr (at most
  :data:`MAX_MESSAGE` characters) and the exit code is 2;
* ``KeyboardInterrupt`` is ``interrupted`` and exit code 130;
* anything else is a bug: its traceback is shown (exit code 1). With the environment
  variable ``SOFTHAND_TRACEBACK=1`` expected failures show their traceback too.

On success :func:`run_cli` returns ``main``'s result (a command whose ``main`` returns an exit
code passes it to ``sys.exit``).

:class:`ArgumentParser` turns argparse's usage errors into :class:`CliError`;
:func:`check_output_dir` / :func:`check_output_file` check an output location before any
work (not a file where a directory is meant, no earlier output overwritten without
``--force``, writable), creating nothing. :func:`parse_kv` reads ``key:value`` command-line
items (``--env-kwargs``) with the bounded YAML loader.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any


class CliError(Exception):
    """A wrong input; :func:`run_cli` prints its message as one line and exits with code 2."""


#: Longest message :func:`run_cli` prints (characters; a message never prints an unbounded
#: structure).
MAX_MESSAGE = 400


def expected_errors() -> tuple[type[BaseException], ...]:
    """The exception types that are a wrong input, not a bug (see the module docstring)."""
    import gymnasium.error
    import yaml

    from softhand_env.physics.hand import PhysicsError

    return (CliError, ValueError, TypeError, PhysicsError, yaml.YAMLError, RecursionError,
            MemoryError, OSError, gymnasium.error.Error)


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line, at most :data:`MAX_MESSAGE` characters; the type
    is named unless ``exc`` is a :class:`CliError`."""
    if isinstance(exc, OSError) and exc.strerror:
        text = exc.strerror + (f": {exc.filename}" if exc.filename else "")
    else:
        try:
            text = str(exc)
        except RecursionError:  # a message built from a deeply nested value
            text = ""
    text = " ".join(text[:4 * MAX_MESSAGE].split())
    if not isinstance(exc, CliError):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    if len(text) > MAX_MESSAGE:
        text = text[:MAX_MESSAGE - 3] + "..."
    return text


def run_cli(main: Callable[[Sequence[str] | None], Any],
            argv: Sequence[str] | None = None) -> Any:
    """Run a command's ``main(argv)`` and return its result; on an expected failure print one
    line on stderr and exit with code 2, on ``KeyboardInterrupt`` exit with code 130; a bug
    raises (traceback, exit code 1)."""
    debug = os.environ.get("SOFTHAND_TRACEBACK", "") not in ("", "0")
    try:
        return main(argv)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        sys.exit(130)
    except expected_errors() as exc:
        if debug:
            raise
        print(f"error: {one_line(exc)}", file=sys.stderr)
        sys.exit(2)


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose usage errors are :class:`CliError` (one line, exit code 2 in
    :func:`run_cli`) instead of a usage block; sub-parsers are of the same class."""

    def error(self, message: str):  # type: ignore[override,unused-ignore]
        raise CliError(f"{self.prog}: {message}")


def check_int(name: str, value: int, low: int, high: int) -> None:
    """:class:`CliError` naming ``name`` unless ``low <= value <= high``."""
    if not low <= value <= high:
        raise CliError(f"{name} must be in [{low}, {high}] (got {value})")


def _probe_writable(directory: Path, what: str) -> None:
    """:class:`CliError` unless a file can be created in ``directory`` (or, if it does not
    exist yet, in its nearest existing ancestor, which must be a directory)."""
    base = directory
    while not base.exists():
        if base.parent == base:
            break
        base = base.parent
    if not base.is_dir():
        raise CliError(f"{what} {directory}: {base} is not a directory")
    try:
        fd, name = tempfile.mkstemp(prefix=".write-probe-", dir=base)
    except OSError as exc:
        raise CliError(f"{what} {directory} is not writable ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(name)


def check_output_dir(out: str | Path, names: Iterable[str], force: bool,
                     what: str = "--out") -> Path:
    """Check the output directory ``out`` before any work; returns it as a Path.

    :class:`CliError` if ``out`` exists and is not a directory, if it holds one of ``names``
    (file names or glob patterns) and ``force`` is not set, or if it cannot be written.
    Nothing is created."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise CliError(f"{what} {path} exists and is not a directory")
    if path.is_dir() and not force:
        found = list(dict.fromkeys(p.name for pattern in names  # in the order of names
                                   for p in sorted(path.glob(pattern))))
        if found:
            shown = ", ".join(found[:5]) + (", ..." if len(found) > 5 else "")
            raise CliError(f"{what} {path} already holds {shown}; pass --force to overwrite "
                           f"or choose another {what}")
    _probe_writable(path, what)
    return path


def check_output_file(out: str | Path, force: bool, what: str = "--out") -> Path:
    """Check the output file ``out`` before any work: :class:`CliError` if it is a directory,
    exists without ``force``, or its directory cannot be written. Nothing is created."""
    path = Path(out)
    if path.is_dir():
        raise CliError(f"{what} {path} is a directory")
    if path.exists() and not force:
        raise CliError(f"{what} {path} exists; pass --force to overwrite it")
    _probe_writable(path.parent, what)
    return path



def parse_kv(items: Sequence[str] | None, what: str = "--env-kwargs") -> dict[str, Any]:
    """``["k:v", ...]`` -> dict, each value parsed as YAML (``0.5``, ``true``, ``[6, 6]``) with the
    bounds of :func:`softhand_env.physics.safe_yaml.load_bounded` (no aliases, depth, size);
    :class:`CliError` naming ``what`` for an item without ``key:`` or an unreadable value."""
    from softhand_env.physics.safe_yaml import load_bounded

    out: dict[str, Any] = {}
    for item in items or ():
        key, sep, value = item.partition(":")
        if not sep or not key:
            raise CliError(f"{what} expects key:value items (got {item[:80]!r})")
        try:
            out[key] = load_bounded(value, source=f"{what} {key[:80]!r}")
        except ValueError as exc:
            raise CliError(str(exc)) from None
    return out
