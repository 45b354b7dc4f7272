"""Emission files solved and rendered: a numbered sequence, and a watched file that another
program rewrites (half-written versions are never loaded)."""
import numpy as np
import pytest

from radtr_addon.blender.pipeline import solve
from radtr_addon.blender.sequence import render_sequence, watch
from radtr_addon.errors import InputFileError
from radtr_addon.settings import Settings


@pytest.fixture
def job(cornell):
    return solve(cornell.context, Settings(max_area=0.01, method="embree", rays=64, solver="direct"),
                 log=lambda *_: None)


def colours(job):
    from radtr_addon.blender.flashlight import LiveMeshes

    return [b.copy() for pair in LiveMeshes(job.objects, job.leaves).snapshot() for b in pair]


def test_sequence_renders_each_file_and_scales_with_it(job, tmp_path):
    E = job.leaves.emission
    for i, scale in ((1, 1.0), (2, 2.0)):
        np.savetxt(tmp_path / f"es_{i}.dat", E * scale)
    np.testing.assert_allclose(job.with_emission(2 * E), 2 * job.result.B, rtol=1e-9)
    before = colours(job)
    paths = render_sequence(job, str(tmp_path / "es_"), 1, 2, tmp_path / "frames", suffix=".dat")
    assert [p.name for p in paths] == ["frame_0001.png", "frame_0002.png"]
    assert all(np.array_equal(a, b) for a, b in zip(colours(job), before))
    with pytest.raises(InputFileError, match="es_3.dat: no such file"):
        render_sequence(job, str(tmp_path / "es_"), 1, 3, tmp_path / "frames", suffix=".dat")


def test_watch_loads_only_complete_versions(job, tmp_path):
    E = job.leaves.emission
    target = tmp_path / "live_es.dat"
    np.savetxt(target, E)
    full = target.read_text()
    script = iter([
        lambda: None,                                    # first version: stable for one poll, then shown
        lambda: None,
        lambda: target.write_text(full[: len(full) // 2]),   # another program half way through a write
        lambda: None,                                    # ... stays half written for a while: refused
        lambda: None,
        lambda: np.savetxt(target, 3 * E),               # the complete new version
        lambda: None,
        lambda: None,
    ])
    logs = []
    shown = watch(job, target, tmp_path / "w", polls=8, sleep=lambda _: next(script)(), log=logs.append)
    assert [p.name for p in shown] == ["watch_0000.png", "watch_0001.png"]
    assert any("waiting for a complete file" in line for line in logs)


def test_clicking_a_patch_toggles_its_emission(job):
    from radtr_addon.blender.sequence import toggle_patch

    leaves = job.leaves
    light = int(np.flatnonzero(leaves.emission.max(axis=1) > 0)[0])
    eye = leaves.centroids[light] + 0.2 * leaves.normals[light]            # in front of the light, looking at it
    i, E = toggle_patch(job, eye, -leaves.normals[light], leaves.emission)
    assert i == light and E[i].max() == 0 and E.sum() < leaves.emission.sum()
    floor = [s.name for s in job.extraction.objects].index("floor")
    f = int(np.flatnonzero(leaves.object_index == floor)[0])
    j, E2 = toggle_patch(job, leaves.centroids[f] + 0.1 * leaves.normals[f], -leaves.normals[f], E)
    assert j == f and np.array_equal(E2[f], E[E.max(axis=1).argmax()])           # on at the brightest emission
    assert toggle_patch(job, [0, 0, 50.0], [0, 0, 1.0], E2)[0] == -1                 # a click on nothing
