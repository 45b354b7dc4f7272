"""Low-rank radiosity against the direct solve, its back-ends against each other, its disk
cache against changes and damage, and the flashlight's light against the closed form."""
import numpy as np
import pytest
from geometry import cube

from radtr_addon.errors import SceneError
from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
from radtr_addon.hierarchy import subdivide
from radtr_addon.lowrank import build
from radtr_addon.lowrank.backends import BACKENDS, make_backend, opencl_build_error, unavailable
from radtr_addon.lowrank.cache import cached_build
from radtr_addon.lowrank.flashlight import Flashlight, Spot, spot_irradiance
from radtr_addon.scene import PatchScene
from radtr_addon.solvers import solve

FF = FormFactorSettings("embree", rays=256)


@pytest.fixture(scope="module")
def box():
    """The closed unit cube (one face emitting) in a 3-level hierarchy, and its rows."""
    s = cube(emission=0.0)
    s.emission[:2] = [3.0, 2.0, 1.0]
    s.rho[:] = [0.7, 0.5, 0.3]
    h = subdivide(s, 1 / 16, 3)
    return h, FormFactors(h.leaves, FF)


def test_leaf_level_reproduces_the_direct_solve(box):
    h, rows = box
    lr = build(h, rows, h.levels)
    assert lr.k == h.leaves.n and abs(lr.V - np.eye(lr.n)).max() == 0          # V = I
    direct = solve("direct", h.leaves, rows).B
    np.testing.assert_allclose(lr.solve(h.leaves.emission), direct, rtol=1e-10)


def test_coarser_levels_approximate_it(box):
    h, rows = box
    direct = solve("direct", h.leaves, rows).B
    errors = []
    for level in range(h.levels + 1):
        B = build(h, rows, level).solve(h.leaves.emission)
        errors.append(np.sqrt(np.mean((B - direct) ** 2) / np.mean(direct ** 2)))
    print("low-rank RMS error per level:", [f"{e:.2e}" for e in errors])
    assert errors[-1] < 1e-12 and errors[0] > 2 * errors[1]     # measured 0.35, 0.083, 0.083, 6.5e-16


def test_a_cut_must_cover_every_patch_once(box):
    from radtr_addon.lowrank import build_cut

    h, rows = box
    whole = [(1, g) for g in range(len(h.representative[1]))]
    with pytest.raises(SceneError, match="uncovered"):
        build_cut(h, rows, whole[1:])
    with pytest.raises(SceneError, match="twice"):
        build_cut(h, rows, whole + [(0, 0)])
    np.testing.assert_allclose(build_cut(h, rows, whole).U, build(h, rows, 1).U)


@pytest.mark.parametrize("name", sorted(BACKENDS))
@pytest.mark.parametrize("mono", [False, True])
def test_backends_match_numpy_float64(box, name, mono):
    if unavailable(name):
        pytest.skip(f"{name} back-end unavailable here: {unavailable(name)}")
    h, rows = box
    lr = build(h, rows, h.levels - 1)
    lr = lr.monochrome() if mono else lr
    rng = np.random.default_rng(0)
    E = rng.uniform(0, 2, (lr.n, lr.channels))
    ref = lr.solve(E)
    backend = make_backend(name, lr, np.float32)
    got = backend.solve(E)
    if backend.exact:
        assert np.abs(got - ref).max() <= 1e-5 * np.abs(ref).max()
        return
    # a compressed U: within its own bound (plus float32 rounding), and far from nothing
    from radtr_addon.lowrank.backends import int8_error_bound

    bound = int8_error_bound(backend.scale, lr.coefficients(E), lr.rho)
    assert np.all(np.abs(got - ref) <= bound + 1e-5 * np.abs(ref).max())
    error = np.abs(got - ref).max() / np.abs(ref - E).max()
    print(f"{name}: largest error {error:.2e} of the largest reflected light, bound {bound.max():.2e}")
    assert 0 < error < 0.02


def test_a_backend_that_cannot_build_is_reported_with_the_reason_and_falls_back(box, monkeypatch):
    from radtr_addon.lowrank import backends

    reason = opencl_build_error("__kernel void product(__global REAL *U) { this is not C; }")
    assert reason and "Error" in reason
    for device in backends.opencl_devices():         # every device was tried, and is named
        assert device.name.strip() in reason
    monkeypatch.setitem(backends._UNAVAILABLE, "opencl", reason)
    h, rows = box
    lr = build(h, rows, h.levels - 1)
    with pytest.raises(backends.BackendUnavailable, match="opencl back-end is unavailable"):
        make_backend("opencl", lr)
    said = []
    fallback = make_backend("opencl", lr, fallback=True, warn=said.append)
    assert isinstance(fallback, backends.NumpyBackend) and "using numpy instead" in said[0]
    E = np.ones((lr.n, lr.channels))
    np.testing.assert_allclose(fallback.solve(E), lr.solve(E), rtol=1e-5)


def test_refuses_a_level_that_does_not_fit_and_names_one_that_does(box):
    h, rows = box
    with pytest.raises(SceneError, match=r"level 3 .* GiB, over the budget .*; level \d \(\d+ clusters\) would fit"):
        build(h, rows, 3, budget_bytes=200_000)


def test_cache_reuses_rebuilds_on_change_and_on_damage(box, tmp_path):
    h, rows = box
    level = h.levels - 1
    first, hit = cached_build(h, rows, level, tmp_path, ff_label=FF.label())
    assert not hit
    again, hit = cached_build(h, rows, level, tmp_path, ff_label=FF.label())
    assert hit and np.array_equal(again.U, first.U)
    np.testing.assert_allclose(again.solve(h.leaves.emission), first.solve(h.leaves.emission), rtol=1e-12)
    # a changed reflectance or a moved vertex is another key
    leaves = h.leaves
    rho, vertices = leaves.rho.copy(), leaves.vertices.copy()
    leaves.rho[0, 0] = 0.2
    _, hit = cached_build(h, FormFactors(leaves, FF), level, tmp_path, ff_label=FF.label())
    assert not hit
    leaves.rho[:] = rho
    leaves.vertices[5, 2] += 1e-3
    _, hit = cached_build(h, FormFactors(leaves, FF), level, tmp_path, ff_label=FF.label())
    assert not hit
    leaves.vertices[:] = vertices
    # a truncated or garbled file is reported and rebuilt
    from radtr_addon.lowrank.cache import cache_key

    path = tmp_path / f"lowrank-{cache_key(h, level, FF.label(), np.float64)}.npz"
    for damaged in (path.read_bytes()[: path.stat().st_size // 2], b"not a zip"):
        path.write_bytes(damaged)
        warnings = []
        rebuilt, hit = cached_build(h, rows, level, tmp_path, ff_label=FF.label(), warnings=warnings)
        assert not hit and "rebuilding" in warnings[0] and path.name in warnings[0]
        np.testing.assert_allclose(rebuilt.U, first.U)
    assert cached_build(h, rows, level, tmp_path, ff_label=FF.label())[1]      # the rebuilt file is good


def plane_and_spot():
    """A 2 x 2 square of 8 x 8 cells (128 triangles) facing +z, and a spot 1 above its centre."""
    g = np.linspace(-1, 1, 9)
    x, y = np.meshgrid(g, g)
    v = np.column_stack([x.ravel(), y.ravel(), np.zeros(81)])
    q = [(r * 9 + c, r * 9 + c + 1, (r + 1) * 9 + c + 1, (r + 1) * 9 + c) for r in range(8) for c in range(8)]
    t = [[a, b, c] for a, b, c, d in q] + [[a, c, d] for a, b, c, d in q]
    return PatchScene(v, t, 0.5, 0.0, 0, 0), Spot(np.array([0, 0, 1.0]), np.array([0, 0, -1.0]),
                                                  angle=np.radians(40), intensity=2.0)


def test_spot_irradiance_is_i_cos_over_r_squared_inside_the_cone():
    from radtr_addon.formfactors.raycast import EmbreeRays

    s, spot = plane_and_spot()
    H = spot_irradiance(s, spot, EmbreeRays(s, 1))
    d = s.centroids - spot.position
    r = np.linalg.norm(d, axis=1)
    inside = (d @ spot.direction) / r >= np.cos(spot.angle)
    expected = np.where(inside, spot.intensity * (1.0 / r) / r ** 2, 0.0)      # cos = height / r, height 1
    np.testing.assert_allclose(H[:, 0], expected, rtol=1e-12)
    assert 0 < inside.sum() < s.n


def test_flashlight_frames_colour_and_mono():
    s, spot = plane_and_spot()
    s.emission[0] = 1e-3                                     # something emits, so the scene validates
    h = subdivide(s, 1.0, 1)
    rows = FormFactors(h.leaves, FF)
    fl = Flashlight(h.leaves, build(h, rows, 1), "numpy")
    B, stages = fl.frame(spot)
    assert set(stages) == {"visibility", "solve"}
    # a single plane reflects nothing onto itself: B = E + rho H exactly
    np.testing.assert_allclose(B, fl.emission(spot), rtol=1e-5, atol=1e-9)
    fl.set_mono(True)
    grey, _ = fl.frame(spot)
    assert np.all(grey[:, 0] == grey[:, 1]) and np.all(grey[:, 1] == grey[:, 2])


@pytest.mark.parametrize("mono", [False, True])
def test_user_backend_every_frame_matches_numpy(box, mono):
    from conftest import ROOT

    from radtr_addon.solvers.user import UserSolverError

    h, rows = box
    lr = build(h, rows, h.levels - 1)
    lr = lr.monochrome() if mono else lr
    E = np.random.default_rng(1).uniform(0, 2, (lr.n, lr.channels))
    user = make_backend("user", lr, user=f"{ROOT / 'examples' / 'direct_solver.py'}:frame")
    np.testing.assert_allclose(user.solve(E), lr.solve(E), rtol=1e-9)
    with pytest.raises(UserSolverError, match="no function 'nothing'"):
        make_backend("user", lr, user=f"{ROOT / 'examples' / 'direct_solver.py'}:nothing")
