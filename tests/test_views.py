"""Debug views of what a patch sees, and the eye that looks out of a patch."""
import numpy as np
import pytest
from geometry import cube

from radtr_addon.formfactors.closed_form import point_to_polygon
from radtr_addon.views import id_colors, patch_view, view_from_patch


def test_paraboloid_view_shares_are_the_form_factors():
    """Nusselt: a wall's share of the disk, seen from the floor's centre, is its form factor."""
    s = cube()
    floor = 0                                             # triangle (0, 2, 3) at z = 0, facing +z
    ids = patch_view(s, floor, "paraboloid", res=512)
    disk = ids != -3
    assert np.all(ids[disk] >= 0)                         # a closed box: every pixel sees a wall
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    c = s.centroids[floor]
    for q, (a, b, cc, d) in enumerate(quads):
        tris = [q, q + 6]                                 # cube() lists the quads' first halves, then the second
        share = np.isin(ids[disk], tris).mean()
        exact = point_to_polygon(c, s.normals[floor], s.vertices[[a, b, cc, d]])
        assert share == pytest.approx(exact, abs=2e-3), q


def test_hemicube_cross_covers_the_hemisphere():
    s = cube()
    ids = patch_view(s, 0, "hemicube", res=64)
    assert ids.shape == (128, 128)
    inside = ids != -3
    assert inside.sum() == 64 * 64 + 4 * 64 * 32          # the top face and four half faces
    assert np.all(ids[inside] >= 0)
    rgb = id_colors(ids)
    assert rgb.shape == (128, 128, 3) and np.allclose(rgb[~inside], 0.5)


def test_view_from_patch_looks_along_the_normal():
    s = cube()
    for i in (0, 3, 7, 11):
        eye, q = view_from_patch(s, i)
        w, x, y, z = q
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(R @ [0, 0, -1.0], s.normals[i], atol=1e-9)
        assert (eye - s.centroids[i]) @ s.normals[i] > 0


def test_sky_view_counts_what_the_sky_form_factors_count():
    from test_lights import plane

    from radtr_addon.sky import sky_factors
    from radtr_addon.views import sky_view

    s = plane(half=1.0, cells=2)
    sky = sky_factors(s, 30, 30, resolution=64)
    for p in (0, 5, len(sky.directions) - 1):
        ids = sky_view(s, sky.directions[p], res=64)
        counts = np.bincount(ids[ids >= 0], minlength=s.n)
        seen = sky.S[p].toarray().ravel() * s.areas            # pixels x pixel area, per patch
        projected = s.areas.sum() * abs(s.normals[0] @ sky.directions[p])
        np.testing.assert_allclose(seen.sum(), projected, rtol=0.05)   # the plane's shadow along the ray
        np.testing.assert_allclose(counts / counts.sum(), seen / seen.sum(), rtol=1e-9)
