"""Every solver against closed forms, against each other and at the extremes, on exact form
factors given as matrices (no GPU, no bpy).

Inside a sphere F_ij = A_j / A_total exactly; any triangles given those form factors form a
closed enclosure, the white furnace: B = E / (1 - rho) everywhere.
"""
import numpy as np
import pytest

from radtr_addon.errors import Cancelled, SceneError, SettingsError
from radtr_addon.formfactors.rows import Row, RowCache
from radtr_addon.scene import PatchScene
from radtr_addon.solvers import SOLVERS, make_solver, solve
from radtr_addon.solvers.queue import ShooterQueue

ITERATIVE = [s for s in SOLVERS if s != "direct"]


def patches(areas, rho, emission):
    """Disjoint right triangles of the given areas (geometry only sets the areas)."""
    n = len(areas)
    legs = np.sqrt(2 * np.asarray(areas, float))
    v = np.zeros((3 * n, 3))
    v[1::3, 0] = legs
    v[2::3, 1] = legs
    v[:, 2] = np.repeat(np.arange(n), 3)
    return PatchScene(v, np.arange(3 * n).reshape(n, 3), rho, emission, 0, 0)


def matrix_rows(F, escaped=None, budget=2 << 30):
    """A row cache serving the rows of the dense matrix F (escaped = 1 - row sum by default)."""
    escaped = 1 - F.sum(axis=1) if escaped is None else escaped

    def compute(ids):
        return [Row(np.flatnonzero(F[i]), F[i][F[i] > 0], float(max(escaped[i], 0.0)), 0.0) for i in ids]
    return RowCache(compute, budget)


def sphere_F(areas):
    return np.tile(areas / areas.sum(), (len(areas), 1))


def open_scene(seed=2, n=30):
    """Random patches with non-reciprocal form factors whose rows sum below 1 (light escapes)."""
    rng = np.random.default_rng(seed)
    s = patches(rng.uniform(0.5, 2, n), rng.uniform(0.1, 0.9, (n, 3)), 0.0)
    s.emission[:3] = [5.0, 4.0, 1.0]
    F = rng.uniform(0, 1, (n, n)) * (rng.uniform(size=(n, n)) < 0.5)
    np.fill_diagonal(F, 0)
    F *= rng.uniform(0.6, 0.95, n)[:, None] / F.sum(axis=1, keepdims=True)
    return s, F


def dense_solution(s, F):
    """B from numpy's dense solver: (I - R K) B = E, K_ij = F_ji A_j / A_i."""
    K = F.T * s.areas[None, :] / s.areas[:, None]
    return np.stack([np.linalg.solve(np.eye(s.n) - s.rho[:, c, None] * K, s.emission[:, c]) for c in range(3)], 1)


def power_error(s, B, exact):
    """sum A |B - exact| / sum A exact, worst channel."""
    a = s.areas[:, None]
    return float(np.max((a * np.abs(B - exact)).sum(axis=0) / (a * exact).sum(axis=0)))


def test_queue_pops_in_argmax_order():
    rng = np.random.default_rng(0)
    values = rng.uniform(size=1000)
    q, brute = ShooterQueue(values), values.copy()
    for _ in range(3000):
        i = q.pop()
        assert i == int(np.argmax(brute))
        brute[i] = 0.0
        ids = np.unique(rng.integers(0, 1000, 40))
        brute[ids] += rng.uniform(size=len(ids))
        q.raise_to(ids, brute[ids])


@pytest.mark.parametrize("method", SOLVERS)
@pytest.mark.parametrize("rho", [0.0, 0.5, 0.9, 0.99, 0.999])
@pytest.mark.parametrize("spread", [1.0, 1e6])
def test_white_furnace(method, rho, spread):
    rng = np.random.default_rng(1)
    areas = np.exp(rng.uniform(0, np.log(spread), 12))
    s = patches(areas, rho, 2.0)
    tol = 1e-3
    r = solve(method, s, matrix_rows(sphere_F(s.areas)), tol=tol, max_iterations=200_000)
    assert r.converged
    exact = 2.0 / (1 - rho)
    if method == "direct":
        np.testing.assert_allclose(r.B, exact, rtol=1e-6)
    else:
        assert power_error(s, r.B, exact) <= tol


def test_closed_scene_with_reflectance_one_is_refused_before_solving():
    s = patches(np.ones(6), [[1.0, 0.5, 0.5]] * 6, 1.0)
    rows = matrix_rows(sphere_F(s.areas))
    for method in SOLVERS:
        with pytest.raises(SceneError, match="never decay in channel R: 6 patches .*patch 0"):
            make_solver(method, s, rows)


def test_reflectance_one_solves_where_light_escapes():
    s, F = open_scene()
    s.rho[:10] = 1.0
    exact = dense_solution(s, F)
    for method in SOLVERS:
        r = solve(method, s, matrix_rows(F), tol=1e-9, max_iterations=100_000)
        np.testing.assert_allclose(r.B, exact, rtol=1e-6)


@pytest.mark.parametrize("change, message", [
    (lambda s: s.emission.__setitem__((3, 1), np.nan), "patch 3 .*emission is NaN or infinite"),
    (lambda s: s.emission.__setitem__((4, 0), np.inf), "patch 4 .*emission is NaN or infinite"),
    (lambda s: s.rho.__setitem__((5, 2), -0.1), "patch 5 .*reflectance is negative"),
    (lambda s: s.rho.__setitem__((6, 2), 1.2), "patch 6 .*reflectance is over 1"),
])
def test_bad_input_is_refused_before_any_row(change, message):
    s, F = open_scene()
    change(s)
    rows = matrix_rows(F)
    for method in SOLVERS:
        with pytest.raises(SceneError, match=message):
            make_solver(method, s, rows)
    assert rows.computed == 0


def test_bad_settings():
    s, F = open_scene()
    with pytest.raises(SettingsError, match="solver must be one of"):
        make_solver("magic", s, matrix_rows(F))
    with pytest.raises(SettingsError, match="tolerance"):
        make_solver("shooting", s, matrix_rows(F), tol=-1)
    with pytest.raises(SettingsError, match="precision"):
        make_solver("jacobi", s, matrix_rows(F), dtype=np.float16)


@pytest.mark.parametrize("method", SOLVERS)
@pytest.mark.parametrize("scale", [1e-30, 1e30])
def test_emission_scale_invariance(method, scale):
    s1, F = open_scene(seed=3)
    s2, _ = open_scene(seed=3)
    s2.emission *= scale
    r1 = solve(method, s1, matrix_rows(F), tol=1e-9)
    r2 = solve(method, s2, matrix_rows(F), tol=1e-9)
    assert r1.iterations == r2.iterations
    np.testing.assert_allclose(r2.B / scale, r1.B, rtol=1e-9)
    np.testing.assert_allclose(r2.escaped / scale, r1.escaped, rtol=1e-9)
    r32 = solve(method, s2, matrix_rows(F), tol=1e-6, dtype=np.float32)
    np.testing.assert_allclose(r32.B / scale, r1.B, rtol=1e-4)


@pytest.mark.parametrize("method", SOLVERS)
def test_solvers_agree_and_conserve_energy_with_non_reciprocal_rows(method):
    s, F = open_scene()
    assert np.abs(s.areas[:, None] * F - (s.areas[:, None] * F).T).max() > 0.1   # far from reciprocal
    exact = dense_solution(s, F)
    tol = 1e-6
    r = solve(method, s, matrix_rows(F), tol=tol, max_iterations=100_000)
    bound = tol * r.emitted.sum() / (1 - s.rho.max()) / (s.areas[:, None] * exact).sum()
    assert power_error(s, r.B, exact) <= bound * 3        # channel sums vs worst channel
    # books from B and F alone: what each patch sends, lands, is absorbed or escapes
    out = s.areas[:, None] * r.B
    landed = F.T @ out
    absorbed = ((1 - s.rho) * landed).sum(axis=0)
    escaped = ((1 - F.sum(axis=1))[:, None] * out).sum(axis=0)
    np.testing.assert_allclose(absorbed + escaped, r.emitted, rtol=1e-5)
    np.testing.assert_allclose(r.escaped, escaped, rtol=1e-5)


def test_gathering_streams_rows_that_do_not_fit():
    s, F = open_scene(n=300)
    for method in ("jacobi", "gauss_seidel"):
        held = matrix_rows(F)
        small = matrix_rows(F, budget=20_000)
        a = solve(method, s, held, tol=1e-8)
        b = solve(method, s, small, tol=1e-8)
        assert a.iterations == b.iterations
        np.testing.assert_allclose(b.B, a.B, rtol=1e-12)
        assert held.computed == s.n and small.computed > 3 * s.n     # recomputed every sweep


def test_gauss_seidel_needs_fewer_sweeps_than_jacobi():
    s, F = open_scene(n=200)
    s.rho[:] = 0.9
    j = solve("jacobi", s, matrix_rows(F), tol=1e-8)
    g = solve("gauss_seidel", s, matrix_rows(F), tol=1e-8)
    assert g.iterations < 0.75 * j.iterations


def test_direct_refuses_what_does_not_fit_with_the_size():
    s, F = open_scene(n=300)
    with pytest.raises(SceneError, match=r"direct solve of 300 form-factor rows needs about .* GiB"):
        make_solver("direct", s, matrix_rows(F, budget=100_000))


def test_shooting_resumes_where_it_stopped():
    s, F = open_scene()
    straight = make_solver("shooting", s, matrix_rows(F), tol=0, max_iterations=100)
    while not straight.step(16):
        pass
    stopped = make_solver("shooting", s, matrix_rows(F), tol=0, max_iterations=40)
    while not stopped.step(16):
        pass
    assert stopped.iterations == 40 and not stopped.converged
    stopped.resume(60)
    while not stopped.step(16):
        pass
    np.testing.assert_array_equal(stopped.result().B, straight.result().B)
    assert stopped.result().residual_history == straight.result().residual_history


def test_ambient_term_shows_the_furnace_answer_before_any_shot():
    rho = 0.8
    s = patches(np.linspace(1, 3, 10), rho, 2.0)
    rows = matrix_rows(sphere_F(s.areas))
    solver = make_solver("shooting", s, rows, tol=1e-9)
    np.testing.assert_allclose(solver.result().display(s.rho), 2.0 / (1 - rho), rtol=1e-12)
    solver.step(5)
    r = solver.result()
    assert power_error(s, r.display(s.rho), 2.0 / (1 - rho)) < 0.1 * power_error(s, r.B, 2.0 / (1 - rho))


def test_cancel_and_iteration_cap():
    s = patches(np.ones(5), 0.9, 1.0)
    with pytest.raises(Cancelled):
        solve("shooting", s, matrix_rows(sphere_F(s.areas)), tol=1e-12, progress=lambda solver: False)
    r = solve("shooting", s, matrix_rows(sphere_F(s.areas)), tol=1e-12, max_iterations=7)
    assert (r.iterations, r.converged) == (7, False)
    assert r.residual_history[0] == pytest.approx(1.0)
    assert len(r.times) == len(r.residual_history) == 8


@pytest.mark.parametrize("method", SOLVERS)
def test_live_energy_readout_accounts_for_all_light(method):
    s, F = open_scene(n=300)
    solver = make_solver(method, s, matrix_rows(F), tol=1e-9)
    readouts = []
    while not solver.step(1):
        readouts.append(solver.energy())
    readouts.append(solver.energy())
    for e in readouts:
        assert sum(e.values()) == pytest.approx(1.0, abs=1e-9), (solver.phase, e)
    assert readouts[0]["unshot"] > 0.5 and readouts[-1]["unshot"] < 1e-8
