"""Shooting against closed forms and a direct solve, with exact form factors (no GPU).

Inside a sphere F_ij = A_j / A_total exactly; any triangles given those form factors form a
closed enclosure, the white furnace: B = E / (1 - rho) everywhere.
"""
import numpy as np
import pytest

from radtr_addon.errors import Cancelled
from radtr_addon.formfactors.rows import Row, RowCache
from radtr_addon.scene import PatchScene
from radtr_addon.solvers.shooting import shoot


def patches(areas, rho, emission):
    """Disjoint right triangles of the given areas (geometry only sets the areas)."""
    n = len(areas)
    legs = np.sqrt(2 * np.asarray(areas, float))
    v = np.zeros((3 * n, 3))
    v[1::3, 0] = legs
    v[2::3, 1] = legs
    v[:, 2] = np.repeat(np.arange(n), 3)
    return PatchScene(v, np.arange(3 * n).reshape(n, 3), rho, emission, 0, 0)


def matrix_rows(F, escaped=None):
    escaped = np.zeros(len(F)) if escaped is None else escaped

    def compute(ids):
        return [Row(np.flatnonzero(F[i]), F[i][F[i] > 0], float(escaped[i]), 0.0) for i in ids]
    return RowCache(compute)


def sphere_F(areas):
    return np.tile(areas / areas.sum(), (len(areas), 1))


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.9, 0.99])
@pytest.mark.parametrize("spread", [1.0, 1e6])
def test_white_furnace(rho, spread):
    rng = np.random.default_rng(1)
    areas = np.exp(rng.uniform(0, np.log(spread), 40))
    s = patches(areas, rho, 2.0)
    r = shoot(s, matrix_rows(sphere_F(s.areas)), tol=1e-10, max_iterations=200_000)
    assert r.converged
    np.testing.assert_allclose(r.B, 2.0 / (1 - rho), rtol=1e-8)
    assert r.balance_error() < 1e-12


def test_matches_direct_solve_with_escape():
    rng = np.random.default_rng(2)
    n = 30
    s = patches(rng.uniform(0.5, 2, n), rng.uniform(0.1, 0.9, (n, 3)), 0.0)
    s.emission[:3] = [5.0, 4.0, 1.0]
    # symmetric G gives reciprocity A_i F_ij = G_ij; scaled so rows sum below 1 (open scene)
    G = rng.uniform(0, 1, (n, n))
    G = G + G.T
    np.fill_diagonal(G, 0)
    F = G / s.areas[:, None]
    F *= 0.9 / F.sum(axis=1).max()
    r = shoot(s, matrix_rows(F, 1 - F.sum(axis=1)), tol=1e-12, max_iterations=100_000)
    direct = np.linalg.solve(np.eye(n)[None] - s.rho.T[:, :, None] * F[None], s.emission.T[:, :, None])
    np.testing.assert_allclose(r.B, direct[:, :, 0].T, rtol=1e-9)
    escaped_direct = ((r.B * s.areas[:, None]) * (1 - F.sum(axis=1))[:, None]).sum(axis=0)
    np.testing.assert_allclose(r.escaped, escaped_direct, rtol=1e-9)
    assert r.balance_error() < 1e-12


@pytest.mark.parametrize("scale", [1e-30, 1e30])
def test_emission_scale_invariance(scale):
    areas = np.array([1.0, 2.0, 3.0, 4.0])
    s1 = patches(areas, 0.7, [[1, 2, 3], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    s2 = patches(areas, 0.7, s1.emission * scale)
    F = sphere_F(areas)
    r1 = shoot(s1, matrix_rows(F), tol=1e-9)
    r2 = shoot(s2, matrix_rows(F), tol=1e-9)
    assert r1.iterations == r2.iterations
    np.testing.assert_allclose(r2.B / scale, r1.B, rtol=1e-9)


def test_cancel_and_iteration_cap():
    s = patches(np.ones(5), 0.9, 1.0)
    with pytest.raises(Cancelled):
        shoot(s, matrix_rows(sphere_F(s.areas)), tol=1e-12, progress=lambda it, res: False)
    r = shoot(s, matrix_rows(sphere_F(s.areas)), tol=1e-12, max_iterations=7)
    assert (r.iterations, r.converged) == (7, False)
    assert r.residual_history[0] == pytest.approx(1.0)
