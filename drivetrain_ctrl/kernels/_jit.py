"""How the kernels are compiled and cached: the ``jit`` decorators and the cache guard.

Every kernel is compiled by numba in nopython mode with numba's on-disk cache, so that a new
process loads the machine code (a fraction of a second) instead of compiling it (minutes).

Cache guard
-----------
Numba keys a function's cache index (``<module>.<function>-<line>.pyXY.nbi`` in
``__pycache__`` or ``NUMBA_CACHE_DIR``) on the *source stamp* of the file that defines the
function, and of that file only (``_SourceFileBackedLocatorMixin.get_source_stamp`` in
``numba/core/caching.py``: a hash of the file). Code from other files is compiled into the
cached machine code too: every ``jit_inline`` helper is inlined at the IR level, and every other
callee is linked into the caller's library. An edit of such a file does not change the caller's
stamp, so the caller keeps loading stale machine code (numba issue #1833; "Notes on Caching" in
numba's developer documentation lists it among the cache's limitations: invalidation does not
see changes in symbols defined in another file). ``simulate_kernel`` (``integrator.py``) inlines
or calls code from every other file of this package.

The guard: every kernel's cache stamp is the hash of all the package's sources
(:func:`package_source_stamp`: the names and contents of the ``*.py`` files in the directory of
the function's file), so an edit of any kernel file makes every kernel's index stale; numba then
recompiles each kernel on its first call and overwrites its cache entry. Where the cache lives
and how entries are named stay numba's choice; when nothing has changed a second process loads
everything from the cache as before.

Mechanism: ``@njit(cache=True)`` calls ``Dispatcher.enable_caching()``, which sets the
dispatcher's ``_cache = FunctionCache(py_func)``. The decorators here do the same with
:class:`KernelCache`, a ``FunctionCache`` whose ``CacheImpl`` lets numba choose the cache
locator as usual (``NUMBA_CACHE_DIR``, the in-tree ``__pycache__``, the user-wide directory, or
``NUMBA_CACHE_LOCATOR_CLASSES``) and wraps it in :class:`PackageStampLocator`, which delegates
everything to it except ``get_source_stamp``: the method numba's abstract ``_CacheLocator``
defines for this ("a timestamp representing the source code's freshness. Can return any
picklable Python object"). Nothing global in numba is changed: other numba code in the process
keeps numba's per-file stamps. Two private attributes are relied on, ``Dispatcher._cache`` and
``CacheImpl._locator`` (as of numba 0.68); ``tests/unit/test_kernel_cache_guard.py``
fails if a numba upgrade changes them: it checks the guard on a synthetic two-file package
(and that numba's own stamp would have loaded stale code there) and that every kernel of this
package carries it.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from numba import njit
from numba.core.caching import CompileResultCacheImpl, FunctionCache, _CacheLocator
from numba.core.dispatcher import Dispatcher
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

_F = TypeVar("_F", bound=Callable[..., Any])


def _source_files(root: str) -> tuple[tuple[str, int, int], ...]:
    """``(name, mtime_ns, size)`` of the ``*.py`` files directly in ``root``, sorted by name."""
    out = []
    with os.scandir(root) as it:
        for e in it:
            if e.name.endswith(".py") and e.is_file():
                st = e.stat()
                out.append((e.name, st.st_mtime_ns, st.st_size))
    return tuple(sorted(out))


@functools.cache
def _hash_sources(root: str, files: tuple[tuple[str, int, int], ...]) -> str:
    # keyed on the files' mtimes and sizes (as numba's own per-file hash): an edit while the
    # process runs is hashed anew
    h = hashlib.sha256()
    for name, _mtime, _size in files:
        with open(os.path.join(root, name), "rb") as f:
            data = f.read()
        h.update(name.encode())
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()


def package_source_stamp(root: str) -> str:
    """Hash (hex) of the names and contents of all ``*.py`` files directly in directory ``root``."""
    root = os.path.abspath(root)
    return _hash_sources(root, _source_files(root))


class PackageStampLocator(_CacheLocator):
    """A numba cache locator: ``inner``'s cache directory and file names, with the source stamp
    of the whole package (:func:`package_source_stamp` of the function's directory) in place of
    the function's own file."""

    def __init__(self, inner: _CacheLocator, py_file: str) -> None:
        self.inner = inner
        self.root = os.path.dirname(os.path.abspath(py_file))

    def ensure_cache_path(self) -> None:
        self.inner.ensure_cache_path()

    def get_cache_path(self) -> str:
        return str(self.inner.get_cache_path())

    def get_source_stamp(self) -> str:
        return package_source_stamp(self.root)

    def get_disambiguator(self) -> str:
        return str(self.inner.get_disambiguator())


class _PackageStampCacheImpl(CompileResultCacheImpl):
    def __init__(self, py_func: Callable[..., Any]) -> None:
        super().__init__(py_func)  # numba chooses the locator (the cache directory)
        self._locator = PackageStampLocator(self._locator, inspect.getfile(py_func))


class KernelCache(FunctionCache):
    """numba's ``FunctionCache`` with the package-wide source stamp (:class:`PackageStampLocator`)."""

    _impl_class = _PackageStampCacheImpl


def _compiler(**options: Any) -> Callable[[_F], Dispatcher[_F]]:
    """``njit(**options)`` with the on-disk cache guarded by :class:`KernelCache`."""
    compile_ = njit(**options)

    def decorate(fn: _F) -> Dispatcher[_F]:
        disp = compile_(fn)
        if isinstance(disp, Dispatcher):  # not a plain function (NUMBA_DISABLE_JIT=1)
            # what Dispatcher.enable_caching() (cache=True) does, with the package-wide stamp
            disp._cache = KernelCache(disp.py_func)  # type: ignore[attr-defined]
        return disp

    return decorate


#: compiled, cached; numpy error model (no Python exceptions on division: ~2x faster). NRT on
#: explicitly: numba lets a callee inherit the caller's NRT flag when it is not set, and such a
#: function called from a ``jit_nonrt`` one (``_mm_insert`` from ``_decide_fast``) must still
#: allocate
jit = _compiler(error_model="numpy", _nrt=True)
#: small helpers inlined into their callers (avoids copying ChainData on every call)
jit_inline = _compiler(error_model="numpy", inline="always")
#: the per-step path, compiled without numba's reference counting (NRT): such a function must not
#: allocate; it only reads and writes the arrays it is given. Reference counting of the ~60 array
#: arguments cost two thirds of the step time (perf: atomic inc/dec in NRT_incref/NRT_decref).
jit_nonrt = _compiler(error_model="numpy", _nrt=False)


def is_cached(disp: Any) -> bool:
    """True if kernel ``disp`` needs no compilation in this process: it is compiled already, or
    numba's on-disk cache holds a fresh entry of it (the package stamp of the guard matches) for
    this machine's code generator. Reads the cache index only (no loading, no compiling)."""
    if getattr(disp, "signatures", None):
        return True
    cache = getattr(disp, "_cache", None)
    cache_file = getattr(cache, "_cache_file", None)
    if cache_file is None:  # caching disabled (e.g. NUMBA_DISABLE_JIT)
        return False
    try:
        index = cache_file._load_index()
        magic = disp.targetctx.codegen().magic_tuple()
    except Exception:  # an unreadable index is a cache miss for numba too
        return False
    return any(len(key) > 1 and key[1] == magic for key in index)
