"""Collection instances take part, each with its own patches and result mesh."""
import numpy as np

from radtr_addon.blender.extract import RESULT_COLLECTION
from radtr_addon.blender.pipeline import solve
from radtr_addon.settings import Settings


def test_a_hundred_instances_solve_and_are_counted(blend):
    bpy = blend
    prop = bpy.data.collections.new("prop")                  # not linked to the scene: only instanced
    mesh = bpy.data.meshes.new("cube")
    v = [(x, y, z) for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (0, 0.2)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(v, [], faces)
    cube = bpy.data.objects.new("cube", mesh)
    prop.objects.link(cube)
    for k in range(100):
        empty = bpy.data.objects.new(f"spot{k:03d}", None)
        empty.instance_type, empty.instance_collection = "COLLECTION", prop
        empty.location = (k % 10 * 0.5, k // 10 * 0.5, 0)
        bpy.context.scene.collection.objects.link(empty)
    lamp = bpy.data.objects.new("lamp", bpy.data.lights.new("lamp", "SUN"))
    bpy.context.scene.collection.objects.link(lamp)
    logs = []
    job = solve(bpy.context, Settings(max_area=0.02, method="embree", rays=16, tolerance=1e-2), log=logs.append)
    assert job.instances == 100 and len(job.extraction.objects) == 100
    assert job.leaves.n == 100 * len(job.leaves.triangles[job.leaves.object_index == 0])
    assert any("(100 instances)" in line for line in logs)
    assert len(bpy.data.collections[RESULT_COLLECTION].objects) == 100
    # each instance sits where its empty puts it
    first = job.leaves.centroids[job.leaves.object_index == 0].mean(axis=0)
    last = job.leaves.centroids[job.leaves.object_index == 99].mean(axis=0)
    np.testing.assert_allclose(last - first, (4.5, 4.5, 0), atol=1e-9)
    # solving again reads the (now hidden) instancers again
    again = solve(bpy.context, Settings(max_area=0.02, method="embree", rays=16, tolerance=1e-2),
                  log=lambda *_: None)
    assert again.leaves.n == job.leaves.n
