"""The FormFactors interface: method selection, cache budget, GPU fallback, degenerate input,
and reciprocity on the Cornell box."""
import numpy as np
import pytest
from geometry import cube

from radtr_addon.errors import GPUUnavailable, SceneError, SettingsError
from radtr_addon.formfactors import FormFactors, FormFactorSettings, RowCache
from radtr_addon.hierarchy import subdivide
from radtr_addon.scene import PatchScene

ALL = [FormFactorSettings("hemicube", 64), FormFactorSettings("paraboloid", 64), FormFactorSettings("embree", rays=256)]


@pytest.mark.parametrize("settings", ALL, ids=lambda s: s.method)
def test_row_and_rows_agree_and_are_cached(gpu, settings):
    leaves = subdivide(cube(), 1 / 8, 1).leaves
    ff = FormFactors(leaves, settings)
    rows = ff.rows([3, 5, 7])
    assert ff.computed == 3
    one = ff.row(5)
    assert ff.computed == 3                       # served from the cache
    assert np.array_equal(one.indices, rows[1].indices) and np.array_equal(one.values, rows[1].values)
    assert abs(one.values.sum() + one.escaped + one.blocked - 1) < 1e-9


def test_bad_settings_are_named():
    with pytest.raises(SettingsError, match="radiance"):
        FormFactorSettings(method="radiance").validate()
    with pytest.raises(SettingsError, match="split mode"):
        FormFactorSettings(method="paraboloid", split="cubic").validate()
    with pytest.raises(SettingsError, match="even"):
        FormFactorSettings(method="hemicube", resolution=33).validate()


def test_without_gpu_the_gpu_methods_fall_back_to_rays(monkeypatch):
    import radtr_addon.formfactors.gpu_context as gc

    def no_gpu():
        raise GPUUnavailable("no GPU drawing context for form factors: test")

    monkeypatch.setattr(gc, "ensure_gpu_context", no_gpu)
    ff = FormFactors(cube(), FormFactorSettings("hemicube", 64, rays=64))
    assert ff.settings.method == "embree"
    assert "Embree" in ff.warnings[0]
    assert ff.row(0).values.sum() == pytest.approx(1.0, abs=1e-9)
    with pytest.raises(GPUUnavailable):
        FormFactors(cube(), FormFactorSettings("hemicube", 64), fallback=False)


def test_cache_refuses_all_rows_over_budget_with_the_size():
    cache = RowCache(lambda ids: [None] * len(ids), budget_bytes=1 << 20)
    with pytest.raises(SceneError, match=r"10,000 form-factor rows needs about 1\.49 GiB"):
        cache.require_all(10_000)
    cache.require_all(200)                              # 16 * 200^2 bytes fit in 1 MiB


def test_cache_projects_from_rows_held(gpu):
    leaves = subdivide(cube(), 1 / 8, 1).leaves
    ff = FormFactors(leaves, FormFactorSettings("hemicube", 64), cache_bytes=1 << 30)
    ff.rows(range(8))
    per_row = ff.bytes / 8
    assert ff.projected_bytes(leaves.n) == pytest.approx(per_row * leaves.n, rel=1e-6)
    small = FormFactors(leaves, FormFactorSettings("hemicube", 64), cache_bytes=int(per_row * 4))
    small.rows(range(8))
    assert len(small.held) <= 4 and small.computed == 8   # the rest is recomputed on demand


def degenerate_scene():
    """A closed cube plus: a zero-area triangle, a sliver, a patch overlapping the floor,
    and a patch 1e-7 above the floor (nearer than any near plane)."""
    c = cube()
    v = np.vstack([c.vertices, [[0.2, 0.2, 0.5], [0.4, 0.4, 0.5], [0.6, 0.6, 0.5]],        # collinear: zero area
                   [[0.1, 0.1, 0.3], [0.9, 0.1, 0.3], [0.5, 0.1 + 1e-7, 0.3]],               # sliver
                   [[0.1, 0.1, 0.0], [0.6, 0.1, 0.0], [0.1, 0.6, 0.0]],                      # on the floor
                   [[0.1, 0.1, 1e-7], [0.6, 0.1, 1e-7], [0.1, 0.6, 1e-7]]])                  # just above it
    t = np.vstack([c.triangles, np.arange(8, 20).reshape(4, 3)])
    return PatchScene(v, t, 0.5, 1.0, 0, 0)


@pytest.mark.parametrize("settings", ALL, ids=lambda s: s.method)
def test_degenerate_input_gives_finite_rows(gpu, settings):
    s = degenerate_scene()
    assert s.areas[12] == 0
    ff = FormFactors(s, settings)
    rows = ff.rows(range(s.n))
    for i, r in enumerate(rows):
        total = r.values.sum() + r.escaped + r.blocked
        assert np.all(np.isfinite(r.values)) and np.isfinite(total), i
        assert np.all(r.values >= 0)
        assert total == pytest.approx(1.0, abs=1e-9), i
    assert rows[12].values.size == 0 and rows[12].escaped == 1.0   # zero area: documented as all escaped
    assert 12 not in np.concatenate([r.indices for r in rows])       # and never seen
    # a lone patch facing nothing: everything escapes
    lone = PatchScene(np.eye(3), [[0, 1, 2]], 0.5, 1.0, 0, 0)
    r = FormFactors(lone, settings).row(0)
    assert r.values.size == 0 and r.escaped == pytest.approx(1.0)


@pytest.fixture(scope="module")
def cornell_patches(addon):
    import bpy

    from radtr_addon.blender.extract import extract, source_objects
    from radtr_addon.blender.scenes import load_bundled

    bpy.ops.wm.read_homefile(use_empty=True)
    load_bundled("cornell_box").build(bpy)
    ctx = bpy.context
    base = extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene
    return subdivide(base, base.areas.sum() / 400, 1).leaves


@pytest.mark.parametrize("settings", [FormFactorSettings("hemicube", 128), FormFactorSettings("paraboloid", 128)],
                         ids=lambda s: s.method)
def test_reciprocity_between_cornell_surfaces(gpu, cornell_patches, settings):
    """A_S F_ST = A_T F_TS for every pair of surfaces with F_ST > 0.01.

    Per patch pair the point-sampled rows do not meet 2 % (adjacent patches see each other
    from their centroids very differently; see the form-factor benchmark); summed over
    surfaces they do, except where a block stands on the floor: floor patches straddling
    the block's footprint and block patches touching the floor at grazing angles (4.5 %).
    """
    s = cornell_patches
    obj = s.object_index
    k = obj.max() + 1
    exchange = np.zeros((k, k))
    for i, r in enumerate(FormFactors(s, settings).rows(range(s.n))):
        np.add.at(exchange[obj[i]], obj[r.indices], s.areas[i] * r.values)
    ff = exchange / np.bincount(obj, s.areas)[:, None]
    names = s.object_names
    contact = {(names.index("floor"), names.index(b)) for b in ("short_block", "tall_block")}
    contact |= {(b, a) for a, b in contact}
    for a, b in zip(*np.nonzero(ff > 0.01)):
        tol = 0.05 if (a, b) in contact else 0.02
        assert exchange[a, b] == pytest.approx(exchange[b, a], rel=tol), (names[a], names[b])


def test_three_methods_light_the_cornell_box_alike(cornell):
    """Independent methods (GPU hemicube, GPU paraboloid, CPU rays) give the same surface radiosity."""
    from radtr_addon.blender.pipeline import SolveJob
    from radtr_addon.settings import Settings

    ctx = cornell.context
    means = {}
    for method in ("hemicube", "paraboloid", "embree"):
        settings = Settings(max_area=0.006, method=method, resolution=128, rays=4096, tolerance=1e-4)
        job = SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer, settings, log=lambda *_: None)
        job.run()
        s = job.leaves
        lit = s.emission.sum(axis=1) == 0
        weights = np.bincount(s.object_index[lit], s.areas[lit], minlength=len(s.object_names))
        sums = np.stack([np.bincount(s.object_index[lit], s.areas[lit] * job.solver.B[lit, c],
                                     minlength=len(s.object_names)) for c in range(3)], axis=1)
        means[method] = sums[weights > 0] / weights[weights > 0, None]
    print({k: np.round(v[:, 0] / means["hemicube"][:, 0], 4) for k, v in means.items()})
    np.testing.assert_allclose(means["paraboloid"], means["hemicube"], rtol=0.02)
    np.testing.assert_allclose(means["embree"], means["hemicube"], rtol=0.02)
