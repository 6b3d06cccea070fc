"""The package stamp on numba's caches (softhand_env.physics.jit_cache): every cached compiled
function of the package carries the digest of all the modules that define such functions, so
that an edit of one recompiles the functions of the others that contain its code."""

from __future__ import annotations

import os
import re
import time

import pytest
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


def _cache_file(path, stamp):
    return caching.IndexDataCacheFile(str(path), "f-1.py311", stamp)


def test_concurrent_saves_of_two_versions_each_keep_their_own_machine_code(tmp_path):
    # two processes compile different versions (keys) of one function at the same time, both
    # saves in flight at once (both data files written before either index update). numba's
    # own save, which reads the index, takes the lowest free data-file number, writes the
    # index, then the data, can give both the number 1 and leave one key naming the other's
    # code when both read the index before either writes it
    import threading

    stamp = jit_cache.sources_digest()
    files = [_cache_file(tmp_path, stamp) for _ in range(2)]
    both_written = threading.Barrier(2)
    for f in files:
        real = f._save_data

        def save_data(name, data, real=real):
            real(name, data)
            both_written.wait(timeout=10)

        f._save_data = save_data
    threads = [threading.Thread(target=f.save, args=(key, data)) for f, key, data in
               zip(files, ("key_a", "key_b"), ("code_a", "code_b"), strict=True)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=20)
    reader = _cache_file(tmp_path, stamp)
    # each key names its own data (the lock keeps both entries); nothing else is left
    assert reader.load("key_a") == "code_a" and reader.load("key_b") == "code_b"
    assert len(list(tmp_path.glob("f-1.py311.*.nbc"))) == 2
    # a new version of key_a gets a new file; the file no entry names is removed once it
    # is old enough not to be another process's save in flight
    old_a = {p.name for p in tmp_path.glob("f-1.py311.*.nbc")}
    reader.save("key_a", "code_a2")
    assert reader.load("key_a") == "code_a2" and reader.load("key_b") == "code_b"
    assert len(list(tmp_path.glob("f-1.py311.*.nbc"))) == 3  # the old one is young
    past = time.time() - jit_cache.ORPHAN_AGE_S - 1
    for p in tmp_path.glob("f-1.py311.*.nbc"):
        os.utime(p, (past, past))
    reader.save("key_b", "code_b2")
    left = {p.name for p in tmp_path.glob("f-1.py311.*.nbc")}
    assert len(left) == 2 and not left & old_a - {reader._load_index()["key_a"]}
    assert reader.load("key_a") == "code_a2" and reader.load("key_b") == "code_b2"


def test_other_functions_keep_numbas_own_save(tmp_path):
    f = _cache_file(tmp_path, ("another stamp", 1))
    f.save("key", "code")
    assert [p.name for p in tmp_path.glob("*.nbc")] == ["f-1.py311.1.nbc"]  # numba's numbering
    assert f.load("key") == "code"
    assert caching.IndexDataCacheFile.save.safe_for == jit_cache.sources_digest()


def _functions(text: str) -> dict[str, tuple[str, str]]:
    """Each top-level compiled function of a module's source: name -> (decorator, body)."""
    found = {}
    for m in re.finditer(r"^@njit\(([^)]*)\)\ndef (\w+)\(", text, re.MULTILINE):
        end = re.search(r"^\S", text[m.end():], re.MULTILINE)
        body = text[m.end(): m.end() + end.start() if end else len(text)]
        found[m.group(2)] = (m.group(1), body)
    return found


def test_no_cached_function_calls_a_parallel_one():
    # numba's cached code of a caller compiled in a process that loaded its parallel=True
    # callee from the cache names the callee's threaded kernel as that process numbered it:
    # the next process that loads the caller crashes. The parallel kernels are called from
    # Python only.
    functions = {}
    for name in jit_cache.JIT_MODULES:
        functions.update(_functions((jit_cache.PACKAGE_DIR / name).read_text()))
    parallel = {f for f, (deco, _) in functions.items() if "parallel=True" in deco}
    assert {"advance_batch_parallel"} <= parallel
    for f, (deco, body) in functions.items():
        if "cache=True" in deco:
            called = {p for p in parallel if re.search(rf"\b{p}\(", body)}
            assert not called, (f, called)


@pytest.mark.slow
def test_a_batched_step_compiled_beside_cached_kernels_loads_in_the_next_process(tmp_path):
    # a copy of the package with a fresh cache: the first process compiles everything; then
    # the batched step's cache is removed, so the second compiles it with the kernels loaded
    # from the cache; the third loads that entry and steps (it crashed, a segmentation fault
    # at the randomised grasp phase, when the batched step called the parallel kernel itself)
    import shutil
    import subprocess
    import sys

    shutil.copytree(jit_cache.PACKAGE_DIR, tmp_path / "softhand_env",
                    ignore=shutil.ignore_patterns("__pycache__"))
    script = ("import gymnasium as gym, softhand_env\n"
              "v = gym.make_vec('SoftHandPoseRandom-v1', num_envs=4,"
              " vectorization_mode='vector_entry_point')\n"
              "v.reset(seed=0)\n"
              "print(softhand_env.__file__)\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}

    def run() -> None:
        out = subprocess.run([sys.executable, "-c", script], env=env, cwd=tmp_path,
                             capture_output=True, text=True, timeout=900)
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.strip().startswith(str(tmp_path)), out.stdout

    run()
    batched = list((tmp_path / "softhand_env" / "physics" / "__pycache__").glob(
        "hand._step_batch-*"))
    assert batched
    for p in batched:
        p.unlink()
    run()
    run()
