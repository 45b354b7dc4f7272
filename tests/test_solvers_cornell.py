"""Every solver on the bundled Cornell box with the same form factors: they agree within the
bound their tolerance gives, and each keeps the energy books of the open box within 0.5%."""
import numpy as np
import pytest

from radtr_addon.blender.extract import extract, source_objects
from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
from radtr_addon.hierarchy import subdivide
from radtr_addon.solvers import SOLVERS, solve

TOL = 1e-4


@pytest.fixture(scope="module")
def box(addon):
    """Leaves of the Cornell box (about 500 patches) and their Embree form factors, shared."""
    import bpy

    from radtr_addon.blender.scenes import load_bundled

    bpy.ops.wm.read_homefile(use_empty=True)
    load_bundled("cornell_box").build(bpy)
    ctx = bpy.context
    leaves = subdivide(extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene,
                       0.006, 1).leaves
    rows = FormFactors(leaves, FormFactorSettings("embree", rays=1024))
    results = {m: solve(m, leaves, rows, tol=TOL, max_iterations=50_000) for m in SOLVERS}
    return leaves, results


@pytest.mark.parametrize("method", [m for m in SOLVERS if m != "direct"])
def test_solvers_agree_with_direct(box, method):
    leaves, results = box
    ref, r = results["direct"].B, results[method].B
    a = leaves.areas[:, None]
    error = (a * np.abs(r - ref)).sum(axis=0)
    bound = TOL * results["direct"].emitted / (1 - leaves.rho.max(axis=0))
    assert results[method].converged
    assert np.all(error <= bound), (error, bound)
    assert np.all(error > 0)            # they are different computations


@pytest.mark.parametrize("method", SOLVERS)
def test_energy_balance_of_the_open_box(box, method):
    r = box[1][method]
    gone = r.absorbed + r.escaped + r.blocked
    np.testing.assert_allclose(gone, r.emitted, rtol=5e-3)
    assert np.all(r.escaped > 0.2 * r.emitted)


def test_float32_accumulation_matches_float64(box):
    leaves, results = box
    from radtr_addon.solvers import make_solver

    ref = results["shooting"]
    rows = FormFactors(leaves, FormFactorSettings("embree", rays=1024))
    s32 = make_solver("shooting", leaves, rows, tol=TOL, max_iterations=50_000, dtype=np.float32)
    while not s32.step(256):
        pass
    r32 = s32.result()
    assert r32.iterations == ref.iterations
    np.testing.assert_allclose(r32.B, ref.B, rtol=1e-4, atol=1e-5 * ref.B.max())
