"""PatchScene checks: bad values are refused naming the patch, object and material."""
import numpy as np
import pytest

from radtr_addon.errors import SceneError
from radtr_addon.scene import PatchScene


def scene(rho=0.5, emission=((1, 1, 1), (0, 0, 0))):
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    return PatchScene(v, [[0, 1, 2], [0, 2, 3]], rho, emission, [0, 1], [0, 1], ["Lamp", "Wall"], ["glow", "paint"])


def test_geometry():
    s = scene()
    np.testing.assert_allclose(s.areas, [0.5, 0.5])
    np.testing.assert_allclose(s.normals, [[0, 0, 1], [0, 0, 1]])
    np.testing.assert_allclose(s.emitted_power(), [0.5, 0.5, 0.5])
    s.validate()


@pytest.mark.parametrize("kwargs, message", [
    ({"emission": ((np.nan, 1, 1), (0, 0, 0))}, "patch 0 .*Lamp.*emission is NaN"),
    ({"emission": ((1, 1, 1), (0, -1, 0))}, "patch 1 .*Wall.*paint.*emission is negative"),
    ({"rho": ((0.5, 0.5, 0.5), (1.01, 0.2, 0.2))}, "patch 1 .*reflectance is over 1"),
    ({"rho": ((-0.1, 0.5, 0.5), (0.5, 0.5, 0.5))}, "patch 0 .*reflectance is negative"),
    ({"emission": 0.0}, "nothing emits"),
])
def test_validate_names_the_offender(kwargs, message):
    with pytest.raises(SceneError, match=message):
        scene(**kwargs).validate()


def test_degenerate_triangles_dropped():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0]], float)
    s = PatchScene(v, [[0, 1, 2], [0, 1, 3]], 0.5, 1.0, 0, 0)
    kept, dropped = s.without_degenerate()
    assert (kept.n, dropped) == (1, 1)
