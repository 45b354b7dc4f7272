"""Sky form factors: an open patch under a uniform sky gets pi L up to the dome's
discretisation error, which shrinks with alpha and beta; blocked and back-facing patches
see less; the CIE overcast sky integrates to its closed form."""
import numpy as np
import pytest
from test_lights import plane

from radtr_addon.errors import SettingsError
from radtr_addon.scene import PatchScene
from radtr_addon.sky import cie_overcast, dome, dome_error, sky_factors, uniform_sky


@pytest.mark.parametrize("alpha, beta", [(30, 30), (10, 10), (5, 5)])
def test_dome_solid_angles_cover_the_hemisphere(alpha, beta):
    d, omega = dome(alpha, beta)
    assert omega.sum() == pytest.approx(2 * np.pi, rel=1e-12)
    assert np.all(d[:, 2] > 0)


def test_dome_error_shrinks_with_the_steps():
    errors = [abs(dome_error(s, s)) for s in (30, 10, 5, 2)]
    print("dome error of pi L for alpha = beta = 30, 10, 5, 2:", [f"{e:.1e}" for e in errors])
    assert errors == sorted(errors, reverse=True) and errors[-1] < 1e-3


def test_open_plane_under_a_uniform_sky_gets_pi_l():
    s = plane(half=1.0, cells=4)
    sky = sky_factors(s, 10, 10, resolution=256)
    H = sky.irradiance(uniform_sky(sky, [1.0, 2.0, 0.5]))
    expected = np.pi * np.array([1.0, 2.0, 0.5]) * (1 + dome_error(10, 10))
    np.testing.assert_allclose(H.mean(axis=0), expected, rtol=0.01)      # pixels: about 1%
    assert sky.S.shape == (len(sky.directions), s.n) and np.all(sky.S.data > 0)


def test_cie_overcast_integrates_to_its_closed_form():
    """Horizontal irradiance of the CIE overcast sky: 7 pi Lz / 9."""
    s = plane(half=1.0, cells=2)
    sky = sky_factors(s, 5, 5, resolution=128)
    H = sky.irradiance(cie_overcast(sky, 1.0))
    np.testing.assert_allclose(H[:, 0].mean(), 7 * np.pi / 9, rtol=0.01)


def test_blocked_and_back_facing_patches_see_less():
    s = plane(half=1.0, cells=2)
    roof = np.array([[-0.5, -0.5, 0.5], [0.5, -0.5, 0.5], [0.5, 0.5, 0.5], [-0.5, 0.5, 0.5]])
    n0 = len(s.vertices)
    v = np.vstack([s.vertices, roof])
    t = np.vstack([s.triangles, [[n0, n0 + 2, n0 + 1], [n0, n0 + 3, n0 + 2]]])   # the roof faces down
    scene = PatchScene(v, t, 0.5, 0.0, 0, 0)
    sky = sky_factors(scene, 10, 10, resolution=128)
    H = sky.irradiance(uniform_sky(sky, 1.0))[:, 0]
    assert np.all(H[:-2] < 0.95 * np.pi) and np.all(H[-2:] == 0)           # shadowed floor; roof faces away


def test_bad_steps():
    with pytest.raises(SettingsError, match="sky steps"):
        dome(0, 10)


def test_apply_sky_in_a_solve(blend):
    from test_light_objects import add_plane

    from radtr_addon.blender.pipeline import solve
    from radtr_addon.settings import Settings
    from radtr_addon.sky import dome_error

    bpy = blend
    add_plane(bpy)
    job = solve(bpy.context, Settings(max_area=0.1, method="embree", rays=16, sky="uniform", sky_radiance=2.0,
                                      sky_step=10.0, sky_resolution=128), log=lambda *_: None)
    expected = np.array([0.8, 0.6, 0.4]) * np.pi * 2.0 * (1 + dome_error(10, 10))
    np.testing.assert_allclose(job.leaves.emission.mean(axis=0), expected, rtol=0.01)
    assert job.sky.S.shape[1] == job.leaves.n
