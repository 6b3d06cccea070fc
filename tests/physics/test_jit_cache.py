"""The package stamp on numba's caches (softhand_env.physics.jit_cache): every cached compiled
function of the package carries the digest of all the modules that define such functions, so
that an edit of one recompiles the functions of the others that contain its code."""

from __future__ import annotations

import re

from numba.core import caching

from softhand_env.envs import fused
from softhand_env.physics import jit_cache, kernel, model, rosenbrock


def _cached_modules() -> set[str]:
    return {p.relative_to(jit_cache.PACKAGE_DIR).as_posix()
            for p in jit_cache.PACKAGE_DIR.rglob("*.py")
            if "cache=True" in p.read_text() and p.name != "jit_cache.py"}


def test_every_module_with_cached_functions_is_stamped_and_imports_the_stamp_first():
    assert set(jit_cache.JIT_MODULES) == _cached_modules()
    for name in jit_cache.JIT_MODULES:
        text = (jit_cache.PACKAGE_DIR / name).read_text()
        first_decorator = re.search(r"^@", text, re.MULTILINE)
        assert first_decorator is not None, name
        assert 0 <= text.find("jit_cache") < first_decorator.start(), name


def test_package_functions_carry_the_package_stamp_others_their_own():
    assert jit_cache.INSTALLED
    stamp = jit_cache.sources_digest()
    for dispatcher in (model.csm_rhs, kernel._rk4_substep, rosenbrock._rhs_lanes,
                       fused.control_step_packed):
        locator = dispatcher._cache._impl.locator
        assert type(locator).__name__ == "PackageStampLocator"
        assert locator.get_source_stamp() == stamp
        # numba's own paths: the in-tree __pycache__ of the defining module (or numba's
        # user-provided / user-wide directory where that is not writable)
        assert locator.get_cache_path() == locator._inner.get_cache_path()

    def outside(x):  # defined outside the package: numba's own locator and stamp
        return x

    locator = caching.FunctionCache(outside)._impl.locator
    assert type(locator).__name__ != "PackageStampLocator"
    assert locator.get_source_stamp() != stamp
    assert jit_cache.install()  # installing again keeps a single stamp locator in front
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    names = [cls.__name__ for cls in impl._locator_classes]
    assert names.count("PackageStampLocator") == 1 and names[0] == "PackageStampLocator"


def test_the_stamp_changes_with_any_module(tmp_path):
    files = []
    for k in range(3):
        f = tmp_path / f"m{k}.py"
        f.write_text(f"x = {k}\n")
        files.append(f)
    before = jit_cache.sources_digest(tuple(files))
    assert jit_cache.sources_digest(tuple(files)) == before and len(before) == 32
    files[1].write_text("x = 10\n")
    assert jit_cache.sources_digest(tuple(files)) != before
