"""Energy on the solved Cornell box: emitted = absorbed + escaped through the open side.

The escape is measured twice, independently: once as the hemicube pixels that see nothing
(the solver's books), once as the power absorbed by a black window patch closing the box.
"""
import numpy as np
import pytest

from radtr_addon.blender.pipeline import solve
from radtr_addon.settings import Settings


def add_window(bpy):
    """A black, non-emitting quad over the open side (y = 0), facing into the box."""
    verts = [(0.0, 0.0, 0.0), (0.556, 0.0, 0.0), (0.556, 0.0, 0.5488), (0.0, 0.0, 0.5488)]
    mesh = bpy.data.meshes.new("window")
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    mat = bpy.data.materials.new("black")
    mat.diffuse_color = (0, 0, 0, 1)
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0, 0, 0, 1)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("window", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


SETTINGS = Settings(max_area=0.003, levels=1, resolution=64, tolerance=1e-3)


@pytest.fixture(scope="module")
def open_box(addon):
    import bpy

    from radtr_addon.blender.scenes import load_bundled

    bpy.ops.wm.read_homefile(use_empty=True)
    load_bundled("cornell_box").build(bpy)
    return solve(bpy.context, SETTINGS, log=lambda *_: None)


def test_books_balance(open_box):
    r, leaves = open_box.result, open_box.leaves
    assert r.converged
    assert r.balance_error() < 1e-9
    # absorbed again, from the radiosity the solve shows: H = (B - E) / rho, absorbed = sum (1 - rho) H A
    H = (r.B - leaves.emission) / leaves.rho
    absorbed = ((1 - leaves.rho) * H * leaves.areas[:, None]).sum(axis=0)
    np.testing.assert_allclose(absorbed, r.absorbed, rtol=1e-9)
    assert np.all(r.escaped > 0.2 * r.emitted)          # a large part leaves by the open side
    # only floor patches straddling a block's footprint see the inside of the block
    assert np.all(r.blocked < 5e-3 * r.emitted)


def test_escape_matches_a_black_window(open_box, cornell):
    bpy = cornell
    add_window(bpy)
    job = solve(bpy.context, SETTINGS, log=lambda *_: None)
    r, open_box = job.result, open_box.result
    window = job.leaves.object_index == [s.name for s in job.extraction.objects].index("window")
    through_window = (r.irradiance[window] * job.leaves.areas[window, None]).sum(axis=0)
    absorbed_walls = ((1 - job.leaves.rho) * r.irradiance * job.leaves.areas[:, None])[~window].sum(axis=0)
    emitted = r.emitted
    np.testing.assert_allclose(through_window, open_box.escaped, rtol=0.01)
    np.testing.assert_allclose(absorbed_walls + through_window + r.unshot, emitted, rtol=0.01)
    np.testing.assert_allclose(open_box.absorbed + open_box.escaped + open_box.unshot, emitted, rtol=0.01)
