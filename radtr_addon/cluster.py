"""Form-factor rows (and the sky's dome points) on a Dask cluster: ``--scheduler local:N`` (a LocalCluster of N worker
processes on this machine) or ``--scheduler tcp://HOST:PORT`` (an existing cluster).

The scene goes to every worker once (``scatter``, broadcast); rows are asked for in blocks of
about equal cost (Embree: the same rays a row, so equal row counts), several blocks a worker
so a slow one does not hold the rest; each worker builds its ray caster once per scene.
Embree rows are seeded by their patch id, so a row is the same bytes wherever it is
computed. A worker that dies mid-block loses nothing: the scheduler runs the block again
elsewhere. A scheduler that cannot be reached is an error before any work starts. The GPU
methods need a drawing context in each worker; they are refused here.
"""
from __future__ import annotations

import atexit
import time

import numpy as np

from .errors import SettingsError

#: Blocks per worker: enough that workers finishing early take the remaining ones.
BLOCKS_PER_WORKER = 4
#: Seconds to wait for a scheduler (and for local workers to start).
CONNECT_TIMEOUT = 10
_CLIENTS: dict[str, object] = {}


def parse(spec: str) -> tuple[str, object]:
    """("local", N) or ("tcp", address) from ``local:N`` or ``tcp://HOST:PORT``."""
    if spec.startswith("local:") and spec[6:].isdigit() and int(spec[6:]) >= 1:
        return "local", int(spec[6:])
    if spec.startswith("tcp://") and ":" in spec[6:]:
        return "tcp", spec
    raise SettingsError(f"scheduler '{spec}' is neither local:N (N worker processes here) nor tcp://HOST:PORT")


def connect(spec: str):
    """A Dask client for ``spec`` (kept for the session, closed at exit)."""
    if spec in _CLIENTS:
        return _CLIENTS[spec]
    kind, where = parse(spec)
    from distributed import Client, LocalCluster

    try:
        if kind == "local":
            cluster = LocalCluster(n_workers=where, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=50)
            client = Client(cluster, timeout=CONNECT_TIMEOUT)
        else:
            client = Client(where, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as exc:
        raise SettingsError(f"cannot reach the Dask scheduler at {spec}: {exc}") from None
    _CLIENTS[spec] = client
    atexit.register(close, spec)
    return client


def close(spec: str):
    client = _CLIENTS.pop(spec, None)
    if client is not None:
        cluster = client.cluster
        client.close()
        if cluster is not None:
            cluster.close()


#: Per worker process: the ray caster of the scattered scene (by its key, a hash of its
#: content: an object id could be reused by the next scene) and settings.
_CASTERS: dict[tuple, object] = {}


def _rows_of_block(scene, scene_key, settings, ids):
    """On a worker: the rows of ``ids`` and the seconds they took."""
    from .formfactors.methods import make_method

    t0 = time.perf_counter()
    key = (scene_key, settings.label(), settings.seed, settings.origins)
    if key not in _CASTERS:
        _CASTERS.clear()                      # one scene at a time per worker
        _CASTERS[key] = make_method(scene, settings)
    return _CASTERS[key].rows(ids), time.perf_counter() - t0


class ClusterRows:
    """``compute(ids) -> list[Row]`` on a cluster, for a ``RowCache`` (``FormFactors.compute_with``)."""

    def __init__(self, client, scene, settings):
        from .formfactors.methods import GPU_METHODS

        if settings.method in GPU_METHODS:
            raise SettingsError(f"the {settings.method} method draws with the GPU, which Dask workers here have no "
                                f"context for; use --method embree with --scheduler")
        self.client, self.settings = client, settings
        t0 = time.perf_counter()
        self.scene = client.scatter(scene, broadcast=True)
        self.seconds = {"scatter": time.perf_counter() - t0, "wall": 0.0, "worker": 0.0}

    @property
    def workers(self) -> int:
        return max(1, len(self.client.scheduler_info()["workers"]))

    def __call__(self, ids: np.ndarray) -> list:
        ids = np.asarray(ids, dtype=np.int64)
        blocks = [b for b in np.array_split(ids, min(len(ids), BLOCKS_PER_WORKER * self.workers)) if len(b)]
        t0 = time.perf_counter()
        futures = self.client.map(_rows_of_block, [self.scene] * len(blocks), [self.scene.key] * len(blocks),
                                  [self.settings] * len(blocks),
                                  blocks, pure=False)
        out = []
        for rows, seconds in self.client.gather(futures):
            out += rows
            self.seconds["worker"] += seconds
        self.seconds["wall"] += time.perf_counter() - t0
        return out


def _dome_block(scene, scene_key, directions, resolution):
    """On a worker: ``sky.dome_rows`` of a block of dome points, with the worker's caster."""
    from .formfactors.raycast import EmbreeRays
    from .sky import dome_rows

    key = (scene_key, "sky")
    if key not in _CASTERS:
        _CASTERS.clear()
        _CASTERS[key] = EmbreeRays(scene, 1)
    return dome_rows(scene, directions, resolution, _CASTERS[key])


def dome_row_steps(spec: str, scene, directions, resolution: int):
    """``sky.dome_rows`` of every dome point on the cluster ``spec``, in blocks (several a
    worker); yields the fraction of blocks done, returns the rows in dome order."""
    from distributed import as_completed

    client = connect(spec)
    workers = max(1, len(client.scheduler_info()["workers"]))
    blocks = [b for b in np.array_split(np.arange(len(directions)), min(len(directions), BLOCKS_PER_WORKER * workers))
              if len(b)]
    remote = client.scatter(scene, broadcast=True)
    futures = [client.submit(_dome_block, remote, remote.key, directions[b], resolution, pure=False)
               for b in blocks]
    order = {f.key: k for k, f in enumerate(futures)}
    done: dict[int, list] = {}
    for future in as_completed(futures):
        done[order[future.key]] = future.result()
        yield len(done) / len(blocks)
    return [row for k in range(len(blocks)) for row in done[k]]
