"""Your own solver in the loop: a Python function that receives the matrices and E, returns B.

``spec`` names it as ``package.module:function`` (importable) or ``path/to/file.py:function``.
It is called once, after the form factors are assembled, as

    function(F=F, E=E, rho=rho, areas=areas) -> B

with F the sparse (CSR) form factors (row i: what patch i sees), E and rho (n, 3) and the
areas (n,); RadTR's own solvers solve B = E + R K B with K = diag(1/A) F^T diag(A) (see
``base``). B must be (n, 3) (or (n,) for grey) and finite. Anything else, or an exception
in the user's code, is reported as a ``UserSolverError`` naming the function, and nothing
in the scene changes. ``examples/direct_solver.py`` is a working example.

The function runs in a worker thread; each solver step waits for it at most ``WAIT``
seconds, so a function that never returns does not hang RadTR: Esc (Cancel) in the panel
drops the job and Ctrl-C ends the CLI ("cancelled") while it runs. Python cannot stop a
thread, so the abandoned function itself runs on, using its CPU and memory, until it
returns or Blender (or the CLI process) exits; there is no time limit of its own.
"""
from __future__ import annotations

import importlib
import importlib.util
import threading
import time
from pathlib import Path

import numpy as np

from ..errors import RadTRError, describe
from .direct import DirectSolver
from .matrix import transport

#: Seconds one solver step waits for the user's function before handing control back.
WAIT = 0.1


class UserSolverError(RadTRError):
    """The user's solver could not be loaded, raised, or returned something unusable."""


def load_user_solver(spec: str):
    """The function ``spec`` names."""
    module_name, sep, func = spec.rpartition(":")
    if not sep or not module_name or not func:
        raise UserSolverError(f"user solver '{spec}': write it as module:function or file.py:function")
    try:
        if module_name.endswith(".py"):
            path = Path(module_name)
            if not path.is_file():
                raise UserSolverError(f"user solver '{spec}': no such file {path}")
            loader = importlib.util.spec_from_file_location(f"radtr_user_{path.stem}", path)
            module = importlib.util.module_from_spec(loader)
            loader.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except UserSolverError:
        raise
    except (Exception, SystemExit) as exc:
        raise UserSolverError(f"user solver '{spec}': loading it raised {describe(exc)}") from None
    fn = getattr(module, func, None)
    if not callable(fn):
        raise UserSolverError(f"user solver '{spec}': the module has no function '{func}'")
    return fn


def call_user_solver(fn, spec: str, n: int, **problem) -> np.ndarray:
    """B (n, 3) from the user's function, checked (an (n, 1) or (n,) answer is grey)."""
    try:
        B = fn(**problem)
    except (Exception, SystemExit) as exc:
        raise UserSolverError(f"user solver '{spec}' raised {describe(exc)}") from None
    if np.iscomplexobj(B):
        raise UserSolverError(f"user solver '{spec}' returned complex numbers (largest imaginary part "
                              f"{np.abs(np.imag(B)).max():.3g}); return real B")
    try:
        B = np.asarray(B, dtype=float)
    except (TypeError, ValueError):
        raise UserSolverError(f"user solver '{spec}' returned {type(B).__name__}, not an array") from None
    if B.shape in ((n,), (n, 1)):
        B = np.repeat(B.reshape(n, 1), 3, axis=1)
    if B.shape != (n, 3):
        raise UserSolverError(f"user solver '{spec}' returned shape {B.shape}; expected ({n}, 3)")
    bad = ~np.isfinite(B).all(axis=1)
    if bad.any():
        raise UserSolverError(f"user solver '{spec}' returned NaN or infinity at patch {int(np.flatnonzero(bad)[0])} "
                              f"({int(bad.sum())} patches in all)")
    return B


class UserSolver(DirectSolver):
    """The direct solve's steps (assemble F, then one solve) with the user's function as the solve."""

    name = "user"

    def __init__(self, scene, rows, *, spec: str, **kw):
        self.spec = spec
        self.function = load_user_solver(spec)
        super().__init__(scene, rows, **kw)

    def _extra_bytes(self, n: int, dense: bool, nnz: int) -> int:
        return 0                                 # the user's function brings its own memory

    def _estimate(self, n: int, nnz: int, rows) -> tuple[float, str]:
        seconds = rows.seconds / max(rows.computed, 1) * (n - len(rows.held))
        return seconds, f"assembling {n:,} form-factor rows"

    _worker = None

    @property
    def phase(self) -> str:
        if self._worker is not None and self.K is None:
            return f"user solver '{self.spec}' running for {time.perf_counter() - self._worker.started:.0f} s"
        return super().phase

    def _advance(self, t0: float):
        if self._worker is None:
            F = self._assembly.step()
            if F is not None:
                self._worker = _Worker(lambda: self._solve(F, None))
                self._F = F
            return
        if not self._worker.wait(max(WAIT - (time.perf_counter() - t0), 0.0)):   # WAIT in all per step
            return
        self._finish(transport(self._F, self.area), self._worker.answer(), t0)
        self._F = None
        if self.done and not self.converged:
            raise UserSolverError(f"user solver '{self.spec}' returned a B whose residual is {self.residual:.3g} "
                                  f"of the emitted power, above the tolerance {self.tol:g}: it does not solve "
                                  f"B = E + R K B (raise the tolerance to accept it)")

    def _solve(self, F, K) -> np.ndarray:
        s = self.scene
        B = call_user_solver(self.function, self.spec, s.n, F=F, E=s.emission.copy(), rho=s.rho.copy(),
                             areas=s.areas.copy())
        return B / self.scale


class _Worker:
    """``fn()`` in a daemon thread; ``answer`` returns its value or raises what it raised."""

    def __init__(self, fn):
        self.started = time.perf_counter()
        self._value, self._error = None, None

        def run():
            try:
                self._value = fn()
            except BaseException as exc:       # KeyboardInterrupt, SystemExit: re-raised in the caller
                self._error = exc
        self._thread = threading.Thread(target=run, name="radtr-user-solver", daemon=True)
        self._thread.start()

    def wait(self, seconds: float) -> bool:
        """True once the function has returned (waiting at most ``seconds``)."""
        self._thread.join(seconds)
        return not self._thread.is_alive()

    def answer(self):
        if self._error is not None:
            raise self._error
        return self._value
