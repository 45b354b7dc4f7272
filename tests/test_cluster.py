"""Form-factor rows on a Dask cluster: the same bytes as in this process (rows, B, low-rank U),
a worker killed mid-run loses nothing, a scheduler that cannot be reached is named at once."""
import os
import signal
import threading
import time

import numpy as np
import pytest
from geometry import cube

from radtr_addon.cluster import ClusterRows, connect
from radtr_addon.errors import SettingsError
from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
from radtr_addon.hierarchy import subdivide
from radtr_addon.pipeline import SceneInput, Solve, solve
from radtr_addon.scene import PatchScene
from radtr_addon.settings import Settings

SPEC = "local:2"


def rows_equal(a, b) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.indices, y.indices) and np.array_equal(x.values, y.values)
        and x.escaped == y.escaped and x.blocked == y.blocked for x, y in zip(a, b))


def test_solve_on_the_cluster_gives_the_same_bytes():
    from radtr_addon.lowrank import build

    settings = dict(method="embree", rays=64, max_area=1 / 200, levels=2, tolerance=1e-6)
    here = Solve(SceneInput(cube()), Settings(**settings), log=lambda *_: None).run().finish()
    there = Solve(SceneInput(cube()), Settings(**settings, scheduler=SPEC), log=lambda *_: None)
    assert there.cluster.seconds["worker"] > 0 and len(there.rows.held) == there.leaves.n    # rows came from workers
    there.run().finish()
    assert here.B.tobytes() == there.B.tobytes()
    assert build(here.hierarchy, here.rows, 1).U.tobytes() == build(there.hierarchy, there.rows, 1).U.tobytes()


def test_a_worker_killed_mid_run_loses_nothing():
    leaves = subdivide(cube(), 1 / 500, 1).leaves
    settings = FormFactorSettings("embree", rays=1024)
    reference = FormFactors(leaves, settings).rows(np.arange(leaves.n))
    client = connect(SPEC)
    rows = ClusterRows(client, leaves, settings)
    pids = list(client.run(os.getpid).values())

    def kill():
        time.sleep(0.3)                                 # inside the first blocks
        os.kill(pids[0], signal.SIGKILL)

    killer = threading.Thread(target=kill)
    killer.start()
    got = rows(np.arange(leaves.n))
    killer.join()
    assert rows.seconds["wall"] > 0.3                   # the kill came while rows were being computed
    with pytest.raises(ProcessLookupError):
        os.kill(pids[0], 0)                             # and the worker is gone
    assert rows_equal(got, reference)


def test_gpu_methods_and_unreachable_schedulers_are_refused_before_work(monkeypatch):
    import radtr_addon.cluster as cluster

    with pytest.raises(SettingsError, match="neither local:N"):
        Settings(method="embree", scheduler="local:two").validate()
    with pytest.raises(SettingsError, match="Dask workers have no GPU context"):
        Settings(method="hemicube", scheduler=SPEC).validate()
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 2)
    t0 = time.perf_counter()
    with pytest.raises(SettingsError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        solve(SceneInput(cube()), Settings(method="embree", rays=16, scheduler="tcp://127.0.0.1:9"),
              log=lambda *_: None)
    assert time.perf_counter() - t0 < 20


def test_cornell_solve_through_blender_on_the_cluster_is_byte_identical(cornell):
    from radtr_addon.blender.pipeline import solve as solve_blend

    settings = dict(method="embree", rays=64, max_area=0.004, tolerance=1e-4)
    here = solve_blend(cornell.context, Settings(**settings), log=lambda *_: None)
    cornell.ops.radtr.clear()
    there = solve_blend(cornell.context, Settings(**settings, scheduler=SPEC), log=lambda *_: None)
    assert here.leaves.n > 500 and here.B.tobytes() == there.B.tobytes()


def test_sky_form_factors_on_the_cluster_are_the_same_matrix():
    from radtr_addon.sky import sky_factors

    inward = cube()
    outward = PatchScene(inward.vertices, inward.triangles[:, ::-1], 0.5, 0.0, 0, 0)   # a box seen from the sky
    leaves = subdivide(outward, 1 / 50, 1).leaves
    here = sky_factors(leaves, 30, 30, 64)
    there = sky_factors(leaves, 30, 30, 64, scheduler=SPEC)
    assert here.S.nnz > 0 and (here.S != there.S).nnz == 0
    np.testing.assert_array_equal(here.directions, there.directions)


def test_a_second_scene_on_the_same_cluster_gets_its_own_rows():
    """Workers keep a caster per scene: the next scene (another shape) must not be traced
    against the last one's."""
    import gc

    settings = FormFactorSettings("embree", rays=64)
    client = connect(SPEC)
    first = subdivide(cube(), 1 / 50, 1).leaves
    ClusterRows(client, first, settings)(np.arange(first.n))
    gc.collect()
    box = cube()
    tall = PatchScene(box.vertices * [1.0, 1.0, 3.0], box.triangles, 0.5, 1.0, 0, 0)
    second = subdivide(tall, 3 / 50, 1).leaves
    got = ClusterRows(client, second, settings)(np.arange(second.n))
    assert rows_equal(got, FormFactors(second, settings).rows(np.arange(second.n)))
