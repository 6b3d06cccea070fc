"""Fixtures of the tools tests: the scripts of ``benchmarks/`` imported as modules."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]


@contextmanager
def benchmark_script(name: str) -> Iterator[ModuleType]:
    """``benchmarks/<name>.py`` imported as the module ``name`` (registered in ``sys.modules``
    while in use, since its dataclasses look their module up); on exit it and the sibling
    scripts it imported (``benchmarks/`` joins ``sys.path``) are removed from ``sys.modules``."""
    folder = ROOT / "benchmarks"
    siblings = {p.stem for p in folder.glob("*.py")}
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        for sibling in siblings:
            sys.modules.pop(sibling, None)
