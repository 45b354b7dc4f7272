"""``bench distributed``: Embree form-factor rows per second in this process and on Dask
``local:1`` and ``local:2`` clusters, on the bundled Cornell box (``--quick``: fewer patches).

Columns: the mean bytes a row takes (sparse: 16 per entry, 64 besides), rows per second and
the speed-up over one worker; the scene's scatter to the
workers, the wall time of the rows, the workers' own compute seconds (summed over workers),
and the overhead (wall x workers - compute: scheduling, transfer of the rows back, idle
tails), all in seconds; ``same_bytes``: every row equal to the in-process one. Target: 1.8x
from one worker to two on 2 cores.
"""
from __future__ import annotations

import time

import numpy as np

from ..cluster import ClusterRows, close, connect
from ..formfactors.methods import FormFactors, FormFactorSettings
from .formfactors import cornell_patches

RAYS = 256


def same(a, b) -> bool:
    return all(np.array_equal(x.indices, y.indices) and np.array_equal(x.values, y.values)
               and x.escaped == y.escaped and x.blocked == y.blocked for x, y in zip(a, b))


def run(quick: bool = False) -> list[dict]:
    leaves = cornell_patches(3584 if quick else 14336)
    settings = FormFactorSettings("embree", rays=RAYS)
    ids = np.arange(leaves.n)
    t0 = time.perf_counter()
    reference = FormFactors(leaves, settings).rows(ids)
    local = time.perf_counter() - t0
    row_bytes = np.mean([r.indices.nbytes + r.values.nbytes + 64 for r in reference])
    out = [{"where": "in-process", "patches": leaves.n, "rays": RAYS, "bytes_per_row": row_bytes,
            "rows_per_s": leaves.n / local,
            "speedup_vs_1": None, "scatter_s": 0.0, "wall_s": local, "compute_s": local, "overhead_s": 0.0,
            "same_bytes": True}]
    for workers in (1, 2):
        spec = f"local:{workers}"
        client = connect(spec)
        rows = ClusterRows(client, leaves, settings)
        got = rows(ids)
        wall = rows.seconds["wall"]
        out.append({"where": spec, "patches": leaves.n, "rays": RAYS, "bytes_per_row": row_bytes,
                    "rows_per_s": leaves.n / wall,
                    "speedup_vs_1": None, "scatter_s": rows.seconds["scatter"], "wall_s": wall,
                    "compute_s": rows.seconds["worker"], "overhead_s": wall * workers - rows.seconds["worker"],
                    "same_bytes": same(got, reference)})
        close(spec)
    one = out[1]["rows_per_s"]
    for row in out:
        row["speedup_vs_1"] = row["rows_per_s"] / one
    return out
