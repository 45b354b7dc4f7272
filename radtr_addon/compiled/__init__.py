"""Compiled (numba) forms of the engine's hottest loops, each beside a numpy form of its own.

numba compiles a kernel at its first use, for the CPU its LLVM detects, on the machine that
runs it, and keeps the code in its cache for that CPU alone (another CPU compiles afresh).
``kernel(name)`` is the compiled wrapper of ``kernels`` by that name, built and tried on
tiny arguments once, or None where numba is missing or cannot build here: a warning says
why, once, and the caller uses its numpy form.
"""
from __future__ import annotations

import importlib.util
import sys
import warnings
from functools import lru_cache
from pathlib import Path

#: The one name ``kernels`` is loaded under, however this package is imported.
MODULE = "radtr_compiled_kernels"


@lru_cache(maxsize=None)
def kernel(name: str):
    try:
        kernels = _kernels()
        wrapper = getattr(kernels, name)
        wrapper(*kernels.SMOKE[name]())
        return wrapper
    except Exception as exc:            # not installed, or its LLVM cannot build for this CPU
        why = (str(exc).strip().splitlines() or [""])[0]
        warnings.warn(f"compiled {name} not built ({type(exc).__name__}: {why}): numpy's form is used, slower",
                      RuntimeWarning, stacklevel=2)
        return None


def _kernels():
    """The ``kernels`` module, as ``MODULE`` whether this package is ``radtr_addon`` (the CLI,
    the tests) or inside the add-on (``radtr.radtr_addon``, ``bl_ext.*``): numba's cache
    names the module its code came from, and an entry written under one name failed to load
    under the other. Loaded afresh where its file is another or has changed since (an
    updated add-on in a running Blender)."""
    path = Path(__file__).with_name("kernels.py").resolve()
    stamp = (str(path), path.stat().st_mtime_ns)
    module = sys.modules.get(MODULE)
    if getattr(module, "STAMP", None) != stamp:
        spec = importlib.util.spec_from_file_location(MODULE, path)
        fresh = importlib.util.module_from_spec(spec)
        fresh.STAMP = stamp
        sys.modules[MODULE] = fresh
        try:
            spec.loader.exec_module(fresh)
        except BaseException:
            if module is None:
                del sys.modules[MODULE]
            else:
                sys.modules[MODULE] = module
            raise
        module = fresh
    return module
