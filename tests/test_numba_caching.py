"""Cached numba kernels call only kernels of their own file.

numba decides whether a cached kernel is stale by its own source file alone: a cached kernel that
calls a compiled kernel of another file keeps running the old callee after that file changes, so
machines with and without a warm cache would behave differently (found in an audit: the
viewpoint planner's ray caster called `grid_raycast._cast`)."""

import importlib
import pkgutil
import types

import pytest
from numba.core.registry import CPUDispatcher

import agents
import filters
import semreloc_env


def _modules():
    for pkg in (filters, semreloc_env, agents):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            yield info.name


def _names(code: types.CodeType) -> set[str]:
    out = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            out |= _names(c)
    return out


def _cached_kernels():
    for name in _modules():
        mod = importlib.import_module(name)
        for attr, obj in vars(mod).items():
            cached = isinstance(obj, CPUDispatcher) and type(obj._cache).__name__ != "NullCache"  # cache=True
            if cached and obj.__module__ == name:
                yield name, attr, obj


def test_the_scan_finds_the_cached_kernels():
    found = {(m, a) for m, a, _ in _cached_kernels()}
    assert ("filters.localization.likelihood_field", "log_likelihood_kernel") in found
    assert ("filters.simulators.grid_raycast", "cast_many_labelled") in found
    assert len(found) >= 10


@pytest.mark.parametrize("module, name, kernel", list(_cached_kernels()), ids=lambda v: v if isinstance(v, str) else "")
def test_cached_kernel_calls_no_kernel_of_another_file(module, name, kernel):
    g = kernel.py_func.__globals__
    foreign = [
        n
        for n in sorted(_names(kernel.py_func.__code__))
        if isinstance(g.get(n), CPUDispatcher)
        and g[n].py_func.__code__.co_filename != kernel.py_func.__code__.co_filename
    ]
    assert not foreign, f"{module}.{name} calls compiled kernels of other files: {foreign}"


def test_a_cache_folder_is_chosen_only_where_numba_would_find_none(tmp_path, monkeypatch):
    # a nineteenth tester's: a read-only install with a read-only home failed at import ("no locator available");
    # with no home, numba made a folder named "~" in the working directory
    import tempfile
    from pathlib import Path

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()

    from filters.numba_cache import choose_cache_dir, fallback_dir, writable

    def only(*ok):
        return lambda p: p in ok

    tree, user = tmp_path / "pkg" / "__pycache__", tmp_path / "home" / ".cache" / "numba"
    assert choose_cache_dir(tree, str(user), "/set/by/user", only()) is None
    assert choose_cache_dir(tree, str(user), "", only(tree)) is None
    assert choose_cache_dir(tree, str(user), "", only(user)) is None
    assert choose_cache_dir(tree, str(user), "", only()) == fallback_dir()
    assert choose_cache_dir(tree, "~/.cache/numba", "", lambda p: True if p != tree else False) == fallback_dir()
    assert writable(tmp_path / "new" / "sub") and not writable(Path("/proc/self/none"))


def test_the_fallback_cache_folder_is_private(tmp_path, monkeypatch):
    # numba's cache files are pickles: a folder in a shared temp dir that others can write, or a symlink there,
    # would let them run code here; such a folder is not used
    import os
    import stat
    import tempfile

    from filters.numba_cache import fallback_dir

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    own = fallback_dir()
    assert own.parent == tmp_path and stat.S_IMODE(os.stat(own).st_mode) == 0o700 and fallback_dir() == own
    os.chmod(own, 0o755)  # the user's own, opened: closed again and used
    assert fallback_dir() == own and stat.S_IMODE(os.stat(own).st_mode) == 0o700
    os.rmdir(own)
    (tmp_path / "target").mkdir(mode=0o700)
    own.symlink_to(tmp_path / "target")  # what another user could plant: not used
    with pytest.warns(UserWarning, match="not a private folder"):
        other = fallback_dir()
    assert other not in (own, tmp_path / "target") and stat.S_IMODE(os.stat(other).st_mode) == 0o700
