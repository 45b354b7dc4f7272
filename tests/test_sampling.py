"""The shared sampling helpers (``radtr_addon.sampling``) against closed forms and properties
that do not depend on how they are written (no bpy, no Embree)."""
import numpy as np
import pytest

from radtr_addon.formfactors.rows import histogram_rows
from radtr_addon.sampling import (
    bounding_box,
    bounding_sphere,
    cone_directions,
    cosine_directions,
    grid_side,
    hit_histogram,
    jittered,
    parallel_rays,
    pixel_centres,
    rotated_frames,
    sphere_points,
    strata,
    stratified,
    tangent_frames,
    triangle_points,
)

#: Chi-square with 3 degrees of freedom exceeded with probability 1e-3.
CHI2_3 = 16.27


def unit_normals(k=200, seed=0):
    n = np.random.default_rng(seed).normal(size=(k, 3))
    n = np.vstack([n, np.eye(3), -np.eye(3), [[0.9, 0.1, 0.0], [0.89, 0.3, 0.1]]])   # both helper axes
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def test_tangent_frames_are_orthonormal_and_right_handed_about_the_normal():
    n = unit_normals()
    t, b = tangent_frames(n)
    for x, y in ((t, t), (b, b)):
        np.testing.assert_allclose(dot(x, y), 1.0, atol=1e-12)
    for x, y in ((t, b), (t, n), (b, n)):
        np.testing.assert_allclose(dot(x, y), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-12)          # (t, b, n) right-handed


def test_rotated_frames_turn_by_the_angle_about_the_normal():
    n = unit_normals(50)
    angles = np.linspace(0, 2 * np.pi, len(n))
    t0, b0 = tangent_frames(n)
    t, b = rotated_frames(n, angles)
    np.testing.assert_allclose(dot(t, t0), np.cos(angles), atol=1e-12)
    np.testing.assert_allclose(dot(t, b0), np.sin(angles), atol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-12)


def chi2(counts):
    expected = counts.sum() / len(counts)
    return float(((counts - expected) ** 2 / expected).sum())


@pytest.mark.parametrize("dim", [2, 3])
def test_triangle_points_are_uniform_over_the_triangle(dim):
    rng = np.random.default_rng(1)
    tri = np.array([[0.0, 0, 0], [3, 0, 0], [1, 2, 0]])[:, :dim]
    u, v = rng.random(40_000), rng.random(40_000)
    p = triangle_points(tri, u, v)
    # barycentric coordinates: all in [0, 1]; the four midpoint sub-triangles (equal areas)
    # hold equal shares: the corner ones where one coordinate is over 1/2, the middle one else
    lam = np.linalg.lstsq(np.vstack([tri.T, np.ones(3)]), np.vstack([p.T, np.ones(len(p))]), rcond=None)[0].T
    assert lam.min() >= -1e-12 and lam.max() <= 1 + 1e-12
    corner = np.argmax(lam > 0.5, axis=1)
    cell = np.where((lam > 0.5).any(axis=1), corner, 3)
    assert chi2(np.bincount(cell, minlength=4)) < CHI2_3
    np.testing.assert_allclose(p.mean(axis=0), tri.mean(axis=0), atol=0.02)


def test_triangle_points_broadcast_one_triangle_set_against_many_samples():
    tris = np.random.default_rng(2).random((5, 1, 3, 3))
    u, v = stratified(4)
    p = triangle_points(tris, u, v)
    assert p.shape == (5, 16, 3)
    np.testing.assert_array_equal(p[3], triangle_points(tris[3, 0], u, v))


def test_sphere_points_lie_on_the_sphere_uniformly():
    rng = np.random.default_rng(3)
    centre = np.array([1.0, -2.0, 0.5])
    p = sphere_points(centre, 2.0, rng.random(40_000), rng.random(40_000))
    np.testing.assert_allclose(np.linalg.norm(p - centre, axis=1), 2.0, rtol=1e-12)
    # Archimedes: z is uniform over [-r, r]; by symmetry so is x
    for axis in (0, 2):
        bins = np.minimum(((p[:, axis] - centre[axis]) / 4 + 0.5) * 4, 3).astype(int)
        assert chi2(np.bincount(bins, minlength=4)) < CHI2_3


@pytest.mark.parametrize("form", ["compiled", "numpy"])
def test_cosine_directions_have_the_cosine_moments(form, monkeypatch):
    """Both forms (compiled where numba builds, numpy's): unit, above the horizon, with the
    moments of the pdf cos / pi, and the same directions."""
    from radtr_addon import compiled

    n = unit_normals(3, seed=4)
    u, v = stratified(64)
    u, v = np.broadcast_to(u, (len(n), len(u))), np.broadcast_to(v, (len(n), len(v)))
    if form == "numpy":
        other = cosine_directions(u, v, n)
        monkeypatch.setattr(compiled, "kernel", lambda name: None)
    elif compiled.kernel("cosine_directions") is None:
        pytest.skip("numba cannot build the kernel here (the warning says why)")
    d = cosine_directions(u, v, n)
    if form == "numpy":
        np.testing.assert_allclose(d, other, rtol=0, atol=1e-14)
    assert d.shape == (len(n), 64 * 64, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    cos = np.einsum("kmc,kc->km", d, n)
    assert cos.min() >= 0
    # E[cos] and E[cos^2] for the pdf cos / pi (the grid's midpoint rule is off by ~1e-4 for sqrt)
    np.testing.assert_allclose(cos.mean(axis=1), 2 / 3, atol=5e-4)
    np.testing.assert_allclose((cos ** 2).mean(axis=1), 1 / 2, atol=1e-9)


def test_cone_directions_lie_at_half_angle_sqrt_u_off_the_axis():
    axis = np.array([0.2, -0.4, 0.8]) / np.linalg.norm([0.2, -0.4, 0.8])
    u, v = stratified(5)
    d = cone_directions(axis, 0.3, u, v)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(d @ axis, np.cos(0.3 * np.sqrt(u)), atol=1e-12)
    # the turn about the axis is 2 pi v, from -t
    t, b = tangent_frames(axis[None])
    across = d - np.outer(d @ axis, axis)
    phi = np.arctan2(across @ -b[0], across @ -t[0]) % (2 * np.pi)
    np.testing.assert_allclose(phi, 2 * np.pi * v, atol=1e-9)


@pytest.mark.parametrize("count, side", [(0, 1), (1, 1), (16, 4), (20, 4), (21, 5), (1024, 32)])
def test_grid_side_is_the_nearest_square(count, side):
    assert grid_side(count) == side


def cells_of(u, v, m):
    return np.floor(u * m).astype(int) * m + np.floor(v * m).astype(int)


def test_stratified_puts_one_sample_in_each_cell_at_its_centre():
    m = 7
    u, v = stratified(m)
    assert np.array_equal(np.sort(cells_of(u, v, m)), np.arange(m * m))
    np.testing.assert_allclose(u * m % 1, 0.5, atol=1e-12)
    np.testing.assert_allclose(v * m % 1, 0.5, atol=1e-12)


def test_jittered_keeps_one_sample_per_cell_and_draws_u_then_v():
    m = 9
    u, v = jittered(m, np.random.default_rng(5))
    assert np.array_equal(np.sort(cells_of(u, v, m)), np.arange(m * m))
    rng = np.random.default_rng(5)
    du, dv = rng.random(m * m), rng.random(m * m)
    np.testing.assert_allclose(u * m - np.floor(u * m), du, atol=1e-9)
    np.testing.assert_allclose(v * m - np.floor(v * m), dv, atol=1e-9)


def test_strata_and_pixel_centres():
    s = strata(4, np.array([[0.0, 0.25, 0.5, 0.999]]))
    np.testing.assert_allclose(s, [[0.0, 0.3125, 0.625, 0.99975]])
    for res in (2, 5, 64):
        c = pixel_centres(res)
        np.testing.assert_allclose(np.diff(c), 2 / res)
        np.testing.assert_allclose([c[0], c[-1]], [-1 + 1 / res, 1 - 1 / res])


def test_hit_histogram_counts_and_sums_per_row():
    rng = np.random.default_rng(6)
    rows, width = 4, 6
    r, c = rng.integers(0, rows, 500), rng.integers(0, width, 500)
    w = rng.random(500)
    counts = hit_histogram(r * width + c, rows, width)
    sums = hit_histogram(r * width + c, rows, width, w)
    assert counts.shape == sums.shape == (rows, width)
    assert counts.sum() == 500
    np.testing.assert_array_equal(counts.sum(axis=1), np.bincount(r, minlength=rows))
    np.testing.assert_allclose(sums.sum(axis=1), np.bincount(r, w, minlength=rows))
    np.testing.assert_array_equal(hit_histogram(np.array([5]), 3, 3), [[0, 0, 0], [0, 0, 1], [0, 0, 0]])


def test_histogram_rows_split_escaped_patches_and_blocked():
    hist = np.array([[0.5, 0.0, 0.25, 0.0, 0.25], [0.0, 0.1, 0.0, 0.9, 0.0]])      # n = 3 patches
    a, b = histogram_rows(hist)
    assert (a.escaped, a.blocked, b.escaped, b.blocked) == (0.5, 0.25, 0.0, 0.0)
    np.testing.assert_array_equal(a.indices, [1])
    np.testing.assert_array_equal(b.indices, [0, 2])
    np.testing.assert_array_equal(b.values, [0.1, 0.9])


def test_bounding_box_and_sphere_hold_the_vertices():
    v = np.random.default_rng(7).normal(size=(100, 3)) * [1, 3, 0.5] + [4, 0, -2]
    centre, diagonal = bounding_box(v)
    np.testing.assert_allclose(centre, (v.min(axis=0) + v.max(axis=0)) / 2)
    assert diagonal == pytest.approx(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    c, r = bounding_sphere(v)
    assert np.linalg.norm(v - c, axis=1).max() < r
    assert bounding_sphere(np.zeros((1, 3)))[1] > 0


def test_parallel_rays_cover_the_sphere_from_outside():
    d = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    centre, radius, res = np.array([1.0, 2.0, 3.0]), 2.0, 8
    origins, dirs = parallel_rays(centre, radius, d, res)
    assert origins.shape == dirs.shape == (res * res, 3)
    np.testing.assert_array_equal(dirs, np.broadcast_to(-d, dirs.shape))
    np.testing.assert_allclose((origins - centre) @ d, 2 * radius, atol=1e-12)      # one plane, outside
    t, b = tangent_frames(d[None])
    x, y = (origins - centre) @ t[0], (origins - centre) @ b[0]
    np.testing.assert_allclose(np.sort(np.unique(x.round(9))), pixel_centres(res) * radius, atol=1e-9)
    np.testing.assert_allclose(y.reshape(res, res)[:, 0], pixel_centres(res) * radius, atol=1e-9)  # bottom-up
    flipped, _ = parallel_rays(centre, radius, d, res, top_down=True)
    np.testing.assert_allclose(flipped.reshape(res, res, 3), origins.reshape(res, res, 3)[::-1], atol=1e-12)
