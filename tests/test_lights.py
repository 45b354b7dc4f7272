"""Direct light from Light objects against closed forms: point, spot, area (square, disk),
sun, shadows, soft shadows and culling (no bpy)."""
import numpy as np
import pytest

from radtr_addon.formfactors.closed_form import point_to_polygon
from radtr_addon.lights import PATCH_POINTS, Light, direct_irradiance
from radtr_addon.scene import PatchScene


def patch_mean(scene, f):
    """Mean of f(points) (k, 3 or k,) over each patch's ``PATCH_POINTS``."""
    pts = np.einsum("pc,ncd->npd", PATCH_POINTS, scene.vertices[scene.triangles])
    vals = np.array([f(pts[:, j]) for j in range(len(PATCH_POINTS))])
    return vals.mean(axis=0)


def plane(half=2.0, cells=16, z=0.0):
    """A square of (2 cells^2) triangles facing +z."""
    g = np.linspace(-half, half, cells + 1)
    x, y = np.meshgrid(g, g)
    m = cells + 1
    v = np.column_stack([x.ravel(), y.ravel(), np.full(m * m, z)])
    q = [(r * m + c, r * m + c + 1, (r + 1) * m + c + 1, (r + 1) * m + c) for r in range(cells) for c in range(cells)]
    t = [[a, b, c] for a, b, c, d in q] + [[a, c, d] for a, b, c, d in q]
    return PatchScene(v, t, 0.5, 0.0, 0, 0)


def at(position, rotation=np.eye(3), scale=1.0):
    m = np.eye(4)
    m[:3, :3] = rotation * scale
    m[:3, 3] = position
    return m


WHITE = np.ones(3)


def test_point_light_is_i_cos_over_d_squared():
    s = plane()
    light = Light("lamp", "POINT", np.array([1.0, 0.5, 0.25]), 100.0, at([0.3, -0.2, 1.5]))
    H, culled = direct_irradiance(s, [light])

    def exact(p):
        d = light.position - p
        r = np.linalg.norm(d, axis=1)
        return 100.0 / (4 * np.pi) * (d[:, 2] / r) / r ** 2
    np.testing.assert_allclose(H, np.outer(patch_mean(s, exact), light.color), rtol=2e-5)   # points lifted 1e-6 x diag
    assert np.all(culled == 0)


def test_sun_is_strength_times_cos():
    s = plane()
    tilt = np.radians(30)
    rot = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    H, _ = direct_irradiance(s, [Light("sun", "SUN", WHITE, 3.0, at([0, 0, 5], rot))])
    np.testing.assert_allclose(H, 3.0 * np.cos(tilt), rtol=1e-12)


@pytest.mark.parametrize("shape", ["SQUARE", "DISK"])
def test_area_light_from_its_closed_form(shape):
    s = plane(half=0.05, cells=1)                      # a small receiver under the light's centre
    light = Light("panel", "AREA", WHITE, 50.0, at([0, 0, 1.0]), shape=shape, size_x=0.8)   # shines along -z
    H, _ = direct_irradiance(s, [light])
    if shape == "DISK":                                # near the axis: F = R^2 / (R^2 + h^2)
        R = 0.4
        np.testing.assert_allclose(H[:, 0], 50.0 / (np.pi * R * R) * R * R / (R * R + 1.0), rtol=0.01)
    else:
        poly = light.polygon()
        expected = patch_mean(s, lambda p: np.array([point_to_polygon(c, [0, 0, 1.0], poly) for c in p]))
        np.testing.assert_allclose(H[:, 0], 50.0 / 0.64 * expected, rtol=2e-5)
    light.matrix = at([0, 0, 1.0], np.diag([1.0, -1.0, -1.0]))     # turned to face up, away from the receiver
    assert np.all(direct_irradiance(s, [light])[0] == 0)


def test_spot_cone_and_blend():
    s = plane(half=3.0, cells=60)                       # 0.1 m cells: a patch spans about 3 degrees here
    spot = Light("spot", "SPOT", WHITE, 100.0, at([0, 0, 1.0]), spot_size=np.radians(60), spot_blend=0.2)
    H, _ = direct_irradiance(s, [spot])
    point, _ = direct_irradiance(s, [Light("p", "POINT", WHITE, 100.0, at([0, 0, 1.0]))])
    angle = np.degrees(np.arctan(np.linalg.norm(s.centroids[:, :2], axis=1)))
    inner = angle < 23                                  # inside the blend band: the point light's value
    np.testing.assert_allclose(H[inner], point[inner], rtol=1e-9)
    assert np.all(H[angle > 33] == 0)
    band = (angle > 28) & (angle < 29.5)
    assert band.any() and np.all((H[band] > 0) & (H[band] < point[band]))


def blocked_plane():
    """``plane`` with a 1 x 1 m square blocker 0.5 m over its centre (its last two triangles)."""
    s = plane()
    blocker = np.array([[-0.5, -0.5, 0.5], [0.5, -0.5, 0.5], [0.5, 0.5, 0.5], [-0.5, 0.5, 0.5]])
    n0 = len(s.vertices)
    t = np.vstack([s.triangles, [[n0, n0 + 1, n0 + 2], [n0, n0 + 2, n0 + 3]]])
    return PatchScene(np.vstack([s.vertices, blocker]), t, 0.5, 0.0, 0, 0)


def test_shadows_hard_and_soft():
    scene = blocked_plane()
    hard = Light("p", "POINT", WHITE, 100.0, at([0, 0, 1.0]))
    H, _ = direct_irradiance(scene, [hard])
    r = np.abs(scene.centroids[:-2, :2]).max(axis=1)
    assert np.all(H[:-2][r < 0.7] == 0) and np.all(H[:-2][r > 1.3] > 0)    # the shadow is 2 x the blocker
    soft = Light("p", "POINT", WHITE, 100.0, at([0, 0, 1.0]), radius=0.3)
    S, _ = direct_irradiance(scene, [soft], samples=64)
    edge = (r > 0.8) & (r < 1.2)
    assert np.any((S[:-2][edge, 0] > 0) & (S[:-2][edge, 0] < 0.95 * H[:-2][edge, 0] + 1e-12))


@pytest.mark.parametrize("light", [
    Light("p", "POINT", WHITE, 100.0, at([0, 0, 1.0]), radius=0.3),
    Light("a", "AREA", WHITE, 100.0, at([0.2, 0, 1.0]), size_x=0.6),
    Light("s", "SUN", WHITE, 3.0, at([0, 0, 5], np.array([[1, 0, 0], [0, 0.8, -0.6], [0, 0.6, 0.8]])), radius=0.3),
], ids=["point", "area", "sun"])
def test_one_shadow_ray_a_point_drawn_afresh_averages_to_a_lights_penumbra(light):
    """What a final gather takes where its rays land (``irradiance_at`` with ``rng``): one
    shadow ray a point to a point of the light drawn afresh. At points across the penumbra
    of a square blocker, 8,000 such rays from each point average to the light seen by
    1,024 rays to fixed points of it within 3% of the unoccluded light there (4 standard
    deviations; the sun's 0.3 rad disk, a 0.3 m lamp, a 0.6 m square panel). The fixed
    points of the panel are even over it: picked by the grid cells' order, its points were
    centred 4 cm off its centre and its penumbra 16% of the light out."""
    from radtr_addon.formfactors.raycast import EmbreeRays
    from radtr_addon.lights import irradiance_at, unoccluded

    caster = EmbreeRays(blocked_plane(), 1)
    k, many = 61, 8000
    points = np.column_stack([np.linspace(-1.5, 1.5, k), np.full(k, 0.1), np.full(k, 1e-4)])
    up = np.tile([0.0, 0.0, 1.0], (k, 1))
    fixed, _ = irradiance_at(points, up, [light], caster, samples=1024, cull=0.0)
    drawn, _ = irradiance_at(np.repeat(points, many, axis=0), np.repeat(up, many, axis=0), [light], caster,
                             cull=0.0, rng=np.random.default_rng(3))
    drawn = drawn.reshape(k, many, 3).mean(axis=1)[:, 0]
    free = unoccluded(light, points, up)
    partial = (fixed[:, 0] > 0.05 * free) & (fixed[:, 0] < 0.95 * free)
    assert partial.sum() >= 4                                             # points in the penumbra
    assert np.all(np.abs(drawn - fixed[:, 0]) <= 0.03 * free)


def test_weak_lights_are_culled_and_reported():
    s = plane()
    strong = Light("strong", "POINT", WHITE, 1000.0, at([0, 0, 1.0]))
    weak = Light("weak", "POINT", WHITE, 1e-4, at([1.0, 0, 1.0]))
    H, culled = direct_irradiance(s, [strong, weak])
    alone, _ = direct_irradiance(s, [strong])
    weak_alone, _ = direct_irradiance(s, [weak])
    np.testing.assert_allclose(H, alone, rtol=1e-12)
    np.testing.assert_allclose(culled, (weak_alone * s.areas[:, None]).sum(axis=0), rtol=1e-9)


def test_uniform_sky_on_an_open_plane_is_pi_l():
    from radtr_addon.lights import sky_irradiance

    s = plane()
    H = sky_irradiance(s, lambda d: np.tile([0.5, 1.0, 2.0], (len(d), 1)))
    np.testing.assert_allclose(H, np.broadcast_to(np.pi * np.array([0.5, 1.0, 2.0]), H.shape), rtol=1e-12)


def test_sky_through_an_opening_is_pi_l_times_the_form_factor():
    """The floor of a unit box open on top sees the sky through the opening only."""
    from radtr_addon.formfactors.closed_form import parallel_rectangles
    from radtr_addon.lights import sky_irradiance

    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2)]   # tests/geometry.cube, no top
    t = [[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads]
    box = PatchScene(v, t, 0.5, 0.0, 0, 0)
    from radtr_addon.hierarchy import subdivide

    leaves = subdivide(box, 1 / 32, 1).leaves
    H = sky_irradiance(leaves, lambda d: np.ones((len(d), 3)), rays=4096)
    floor = np.abs(leaves.centroids[:, 2]) < 1e-9
    mean = (H[floor, 0] * leaves.areas[floor]).sum() / leaves.areas[floor].sum()
    np.testing.assert_allclose(mean, np.pi * parallel_rectangles(1, 1, 1), rtol=0.01)


def test_environment_image_lookup_follows_cycles_mapping():
    from radtr_addon.lights import equirect_lookup

    img = np.zeros((4, 8, 3))
    img[:2] = 1.0                                     # the top half (z > 0) bright
    img[:, 4:, 1] = 2.0                               # u > 1/2: directions with atan2(y, x) < 0 (y < 0)
    f = equirect_lookup(img)
    d = np.array([[0, 0, 1.0], [0, 0, -1.0], [0.0, -1, 0.1], [0.0, 1, 0.1]])
    got = f(d)
    assert got[0, 0] == 1 and got[1, 0] == 0 and got[2, 1] == 2 and got[3, 1] != 2


@pytest.mark.parametrize("scale", [1e-8, 1.0, 1e8])
def test_the_back_of_an_emitter_lights_a_ceiling_1_mm_above_it_at_any_scale(scale):
    """A two-sided lamp (0.5 m square, exitance E) 1 mm under a ceiling, in a 4 m room: the
    ceiling above it gets E x F from the lamp's back, F the closed form (0.99 here), whatever
    the units; shadow rays must not end inside the lamp they aim at."""
    ceiling = plane(half=2.0, cells=32, z=0.0)
    ceiling.triangles = ceiling.triangles[:, ::-1].copy()          # faces down
    lamp = np.array([[-0.25, -0.25, -1e-3], [0.25, -0.25, -1e-3], [0.25, 0.25, -1e-3]])
    lamp2 = np.array([[-0.25, -0.25, -1e-3], [0.25, 0.25, -1e-3], [-0.25, 0.25, -1e-3]])
    floor = np.array([[-2, -2, -4.0], [2, -2, -4.0], [2, 2, -4.0]])
    V = np.vstack([ceiling.vertices, lamp, lamp2, floor]) * scale
    T = np.vstack([ceiling.triangles, np.arange(3) + len(ceiling.vertices), np.arange(3, 6) + len(ceiling.vertices),
                   np.arange(6, 9) + len(ceiling.vertices)])
    scene = PatchScene(V, T, 0.5, 0.0, 0, 0)
    E = np.array([10.0, 10.0, 10.0])
    # the lamp faces down (its front); its back faces the ceiling
    backs = [Light.back_of(f"back {k}", t[::-1] * scale, E) for k, t in enumerate((lamp, lamp2))]
    H, _ = direct_irradiance(scene, backs)
    corners = scene.vertices[scene.triangles[:len(ceiling.triangles)], :2]
    above = np.flatnonzero(np.abs(corners).max(axis=(1, 2)) < 0.2 * scale)
    pts = np.einsum("pc,ncd->npd", PATCH_POINTS, scene.vertices[scene.triangles[above]])
    square = np.vstack([lamp[:2], lamp2[1:]]) * scale
    down = np.array([0, 0, -1.0])
    exact = np.array([[point_to_polygon(p, down, square) for p in patch] for patch in pts]).mean(axis=1)
    assert exact.min() > 0.98 and len(above) == 8
    np.testing.assert_allclose(H[above, 0], 10.0 * exact, rtol=0.01)
