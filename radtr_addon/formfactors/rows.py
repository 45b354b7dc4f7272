"""Sparse form-factor rows and a row cache with a memory budget."""
from __future__ import annotations

import time
from typing import Callable, NamedTuple

import numpy as np

from ..errors import SceneError


class Row(NamedTuple):
    """One form-factor row of patch i: F[i, indices] = values."""

    indices: np.ndarray  # (m,) int64 patch ids, sorted
    values: np.ndarray   # (m,) float64
    escaped: float       # fraction leaving the scene
    blocked: float       # fraction hitting back faces (absorbed there)


def escaped_row() -> Row:
    """The row of a patch that sees nothing: all of its (zero) power escapes."""
    return Row(np.zeros(0, dtype=np.int64), np.zeros(0), 1.0, 0.0)


def histogram_rows(hist: np.ndarray) -> list[Row]:
    """Rows from a hit histogram (k, n + 2): column 0 escaped, 1..n the patches, n + 1 blocked."""
    n = hist.shape[1] - 2
    out = []
    for row in hist:
        idx = np.flatnonzero(row[1:n + 1])
        out.append(Row(idx, row[1:n + 1][idx], float(row[0]), float(row[n + 1])))
    return out


def rows_skipping_degenerate(scene, ids, compute) -> list[Row]:
    """``compute(ids)`` for patches with a positive area; zero-area patches get ``escaped_row``."""
    ids = np.asarray(ids, dtype=np.int64)
    ok = scene.areas[ids] > 0
    good = iter(compute(ids[ok]) if ok.any() else [])
    return [next(good) if k else escaped_row() for k in ok]


class RowCache:
    """Rows computed by ``compute(ids) -> list[Row]`` in batches, kept while they fit.

    ``budget_bytes`` caps what is kept; rows beyond it are recomputed when asked again.
    A solver that needs every row asks ``projected_bytes`` first: gathering streams the rows,
    recomputing them, when they will not fit; the direct solve calls ``require_all``, which
    refuses with the size.
    """

    def __init__(self, compute: Callable[[np.ndarray], list[Row]], budget_bytes: int = 2 << 30):
        self._compute = compute
        self.budget_bytes = budget_bytes
        self.bytes = 0
        self.held: dict[int, Row] = {}
        self.computed = 0
        self.seconds = 0.0

    def projected_bytes(self, n: int) -> int:
        """Bytes all n rows would take: the mean of the rows held so far, else dense (16 n^2)."""
        if self.held:
            return int(self.bytes / len(self.held) * n)
        return 16 * n * n + 64 * n

    def require_all(self, n: int, extra_bytes: int = 0, why: str = "keeping all"):
        """Raise SceneError when n rows (plus ``extra_bytes``) are not expected to fit in the budget."""
        need = self.projected_bytes(n) + extra_bytes
        if need > self.budget_bytes:
            raise SceneError(
                f"{why} {n:,} form-factor rows needs about {need / 2**30:.2f} GiB, over the "
                f"cache budget of {self.budget_bytes / 2**30:.2f} GiB: raise the budget, use fewer "
                f"patches, or a solver that recomputes rows (shooting, Jacobi, Gauss-Seidel)")

    def compute_with(self, compute: Callable[[np.ndarray], list[Row]]):
        """Compute missing rows with ``compute`` from now on (e.g. ``cluster.ClusterRows``)."""
        self._compute = compute

    def prefetch(self, ids, chunk: int = 4096) -> int:
        """Compute and keep the rows of ``ids``, ``chunk`` at a time, until the budget is full;
        returns how many are held (the rest are computed when asked)."""
        ids = np.asarray(ids, dtype=np.int64)
        for start in range(0, len(ids), chunk):
            if self.bytes >= self.budget_bytes:
                break
            self.rows(ids[start:start + chunk])
        return len(self.held)

    def row(self, i: int) -> Row:
        return self.get(int(i))

    def get(self, i: int, prefetch: Callable[[], np.ndarray] | None = None) -> Row:
        """Row i; on a miss also compute the rows ``prefetch()`` names, not held yet (one batch)."""
        row = self.held.get(i)
        if row is not None:
            return row
        extra = [int(j) for j in prefetch()] if prefetch is not None else []
        return self.rows([i] + extra)[0]

    def rows(self, ids) -> list[Row]:
        """Rows of ``ids``: held ones from the cache, the others computed in one batch."""
        ids = [int(i) for i in ids]
        missing = list(dict.fromkeys(i for i in ids if i not in self.held))
        fresh: dict[int, Row] = {}
        if missing:
            t0 = time.perf_counter()
            computed = self._compute(np.asarray(missing, dtype=np.int64))
            self.seconds += time.perf_counter() - t0
            for j, r in zip(missing, computed):
                self.computed += 1
                fresh[j] = r
                size = r.indices.nbytes + r.values.nbytes + 64
                if self.bytes + size <= self.budget_bytes:
                    self.held[j] = r
                    self.bytes += size
        out = [self.held.get(i) or fresh.get(i) for i in ids]
        if any(r is None for r in out):
            raise SceneError(f"form-factor method returned no row for patch {ids[out.index(None)]}")
        return out
