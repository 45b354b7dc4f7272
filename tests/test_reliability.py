"""Bad and extreme input: each case gets a clear error naming what is wrong, and a failure
leaves the Blender file as it was (object and mesh names, meshes' data and modifiers)."""
import json
import re
from types import SimpleNamespace

import numpy as np
import pytest

from radtr_addon.blender.pipeline import SolveJob, solve
from radtr_addon.errors import InputFileError, RadTRError, SceneError, SettingsError
from radtr_addon.settings import Settings

FAST = dict(max_area=0.01, method="embree", rays=16, tolerance=1e-2)


def state(bpy):
    """Everything a failed solve must leave as it was."""
    objects = sorted((o.name, o.data.name if o.data else None, len(o.modifiers), o.hide_get(), o.hide_render)
                     for o in bpy.data.objects)
    meshes = {}
    for m in bpy.data.meshes:
        co = np.empty(len(m.vertices) * 3)
        m.vertices.foreach_get("co", co)
        meshes[m.name] = (len(m.polygons), co.round(6).tobytes(), sorted(a.name for a in m.attributes))
    return objects, meshes


def quiet(*_):
    pass


# -- a Replace solve that fails halfway -------------------------------------------------------

def test_replace_with_a_zero_scale_object_is_refused_before_any_work(cornell):
    bpy = cornell
    bpy.data.objects["short_block"].scale = (1, 1, 0)
    before = state(bpy)
    with pytest.raises(SceneError, match="object 'short_block' has a zero scale along an axis"):
        solve(bpy.context, Settings(mode="REPLACE", **FAST), log=quiet)
    assert state(bpy) == before


def test_replace_failing_while_writing_changes_nothing(cornell, monkeypatch):
    from radtr_addon.blender import write

    bpy = cornell
    bpy.data.objects["floor"].modifiers.new("bevel", "BEVEL")
    before = state(bpy)
    calls = []

    def to_local(mesh, matrix):
        calls.append(mesh.name)
        if len(calls) == 4:
            raise ValueError("disk full")
        real_to_local(mesh, matrix)

    real_to_local = write._to_local
    monkeypatch.setattr(write, "_to_local", to_local)
    with pytest.raises(ValueError, match="disk full"):
        solve(bpy.context, Settings(mode="REPLACE", **FAST), log=quiet)
    assert len(calls) == 4 and state(bpy) == before


def test_replace_that_succeeds_keeps_each_object_in_place(cornell):
    bpy = cornell
    floor = bpy.data.objects["floor"]
    floor.scale = (2, 1, 1)
    lo = np.array([floor.matrix_world @ v.co for v in floor.data.vertices]).min(axis=0)
    solve(bpy.context, Settings(mode="REPLACE", **FAST), log=quiet)
    assert floor.data.name == "floor_radtr"
    after = np.array([floor.matrix_world @ v.co for v in floor.data.vertices]).min(axis=0)
    np.testing.assert_allclose(after, lo, atol=1e-5)


def test_modal_solve_that_raises_is_cleared_and_reported(addon, cornell):
    import radtr.operators.session as op

    reports = []
    wm = SimpleNamespace(event_timer_remove=quiet, progress_end=quiet, progress_update=quiet)
    context = SimpleNamespace(window_manager=wm, workspace=SimpleNamespace(status_text_set=quiet),
                              screen=SimpleNamespace(areas=[]))

    def advance(seconds):
        raise ZeroDivisionError("division by zero")

    op.running["job"] = SimpleNamespace(advance=advance)
    modal = SimpleNamespace(_timer=None, report=lambda kind, msg: reports.append((kind, msg)),
                            _end=lambda ctx: op.ModalSolve._end(modal, ctx),
                            _close=lambda ctx: op.ModalSolve._close(modal, ctx))
    assert op.ModalSolve.modal(modal, context, SimpleNamespace(type="TIMER")) == {"CANCELLED"}
    assert op.running["job"] is None
    assert reports == [({"ERROR"}, reports[0][1])]
    assert reports[0][1].startswith("unexpected error: ZeroDivisionError: division by zero (test_reliability.py:")
    assert addon.operators.solve.RADTR_OT_solve.poll(cornell.context)


# -- bad settings ------------------------------------------------------------------------------

NAN = float("nan")


@pytest.mark.parametrize("kw, message", [
    (dict(max_reflectance=NAN), "max reflectance must be between 0 and 1, got nan"),
    (dict(max_reflectance=-1.0), "max reflectance must be between 0 and 1, got -1.0"),
    (dict(sky="uniform", sky_radiance=NAN), "sky radiance must be 0 or more, got nan"),
    (dict(gather_rays=-4), r"gather rays must be -1 \(auto\), 0 \(none\) or more, got -4"),
    (dict(exposure=NAN), "exposure must be 0 or more, got nan"),
    (dict(exposure=-2.0), "exposure must be 0 or more, got -2.0"),
    (dict(tolerance=NAN), "tolerance must be 0 or more, got nan"),
    (dict(max_area=NAN), r"max area must be 0 \(auto\) or more, got nan"),
    (dict(sky_step=0.0), "sky step must be above 0 and at most 90 degrees, got 0.0"),
    (dict(resolution=16384), r"a hemicube view of 805,306,368 pixels \(resolution 16384\) needs 60.0 GiB, "
                             r"over the memory budget of 2,048 MB \(raise the budget"),
    (dict(method="paraboloid", resolution=16384), "a paraboloid view of 268,435,456 pixels .* needs 20.0 GiB"),
    (dict(method="embree", rays=400_000_000), "casting 400,000,000 rays per patch needs 59.6 GiB"),
    (dict(gather_rays=100_000_000), "gathering 100,000,000 rays per vertex needs 14.9 GiB"),
    (dict(sky="uniform", sky_step=0.001), r"a sky dome of 32,400,000,000 points \(steps 0.001 x 0.001 degrees\) needs"),
    (dict(solver="hierarchical", quality=1e-9), "quality must be between 1e-4 and 1 .*, got 1e-09"),
    (dict(solver="hierarchical", quality=NAN), "quality must be between 1e-4 and 1"),
])
def test_bad_settings_are_refused_naming_the_setting(kw, message):
    with pytest.raises(SettingsError, match=message):
        Settings(**kw).validate()


def test_the_memory_budget_can_be_raised():
    with pytest.raises(SettingsError, match="casting 16,000,000 rays per patch needs 2.4 GiB"):
        Settings(method="embree", rays=16_000_000).validate()
    Settings(method="embree", rays=16_000_000, cache_mb=4096).validate()


def test_sky_form_factors_over_the_budget_are_refused_with_the_patch_count(cornell):
    bpy = cornell
    before = state(bpy)
    refused = r"a sky dome of 8,100 points \(steps 2 x 2 degrees\) x [\d,]+ patches needs [\d,]+ MB"
    with pytest.raises(SettingsError, match=refused):
        solve(bpy.context, Settings(sky="uniform", sky_step=2.0, cache_mb=20, **FAST), log=quiet)
    assert state(bpy) == before


def test_operator_refuses_huge_work_before_starting(cornell):
    from test_addon import small

    bpy = cornell
    small(bpy, method="embree", rays=400_000_000)
    before = state(bpy)
    with pytest.raises(RuntimeError, match="casting 400,000,000 rays per patch needs 59.6 GiB"):
        bpy.ops.radtr.solve()
    assert state(bpy) == before


def poses(tmp_path, **pose):
    path = tmp_path / "poses.json"
    path.write_text(json.dumps([{"position": [0.3, 0.3, 0.3], "direction": [0, 0, -1], **pose}]))
    return str(path)


@pytest.mark.parametrize("args, message", [
    (["solve", "cornell_box", "--max-reflectance", "nan"], "max reflectance must be between 0 and 1, got nan"),
    (["solve", "cornell_box", "--sky", "cie", "--sky-radiance", "nan"], "sky radiance must be 0 or more, got nan"),
    (["solve", "cornell_box", "--gather-rays", "-2"], "gather rays must be -1 .* got -2"),
    (["solve", "cornell_box", "--exposure", "-1"], "exposure must be 0 or more, got -1.0"),
    (["solve", "cornell_box", "--sky", "uniform", "--sky-step", "0.001"], "a sky dome of 32,400,000,000 points"),
    (["solve", "cornell_box", "--out", "{tmp}/missing/r.blend"], "--out .*: the folder .*missing does not exist"),
    (["solve", "cornell_box", "--render", "{tmp}/missing/r.png"], "--render .*: the folder .*missing does not exist"),
    (["export", "cornell_box", "--out", "{tmp}/missing/f.npz"], "--out .*: the folder .*missing does not exist"),
    (["sequence", "cornell_box", "--prefix", "e", "--to", "2", "--out-dir", "{tmp}/poses.json"],
     "--out-dir .*poses.json is a file, not a folder"),
    (["flashlight", "cornell_box", "--poses", "{poses}", "--levels", "2", "--level", "9"],
     r"--level 9 is not a level of the hierarchy: 0..2 with --levels 2"),
])
def test_cli_refuses_bad_settings_and_paths_before_any_work(cornell, tmp_path, capsys, args, message):
    from radtr_addon.cli import main

    bpy = cornell
    before = state(bpy)
    fill = {"tmp": tmp_path, "poses": poses(tmp_path)}
    assert main([a.format(**fill) for a in args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("RadTR error: ") and re.search(message, err), err
    assert state(bpy) == before                 # nothing was opened, solved or written


def test_flashlight_pose_with_nan_intensity_is_refused(tmp_path):
    from radtr_addon.cli import read_poses

    with pytest.raises(RadTRError, match=r"poses.json: pose 0 has a NaN, infinite or negative value \(intensity nan"):
        read_poses(poses(tmp_path, intensity=NAN))


@pytest.mark.parametrize("text, message", [
    ('[{"position": [0, 0, 1], "direction": [0, 0, -1]}, []]', "pose 1 is an empty list"),
    ('[[{"position": [0, 0, 1], "direction": [0, 0, -1]}, "foo"]]', "pose 0, spot 1 is not a spot with position"),
    ('[{"position": [0, 0], "direction": [0, 0, -1]}]', r"pose 0 is not a spot with position and direction"),
    ("[]", "no poses"),
    ("{not json", "not a JSON list of poses"),
])
def test_flashlight_poses_are_checked_before_any_work_naming_the_pose(tmp_path, text, message):
    from radtr_addon.cli import read_poses

    path = tmp_path / "poses.json"
    path.write_text(text)
    with pytest.raises(RadTRError, match=message):
        read_poses(str(path))


@pytest.mark.parametrize("flags, message", [
    (["--backend", "cuda"], "--backend cuda: the back-ends are numpy, numba"),
    (["--backend", "user"], "--backend user calls your function every frame: name it with --user-frame"),
    (["--solver", "hierarchical"], "the flashlight needs the low-rank factors of the uniform patch hierarchy"),
])
def test_flashlight_settings_are_refused_before_the_solve(tmp_path, capsys, monkeypatch, flags, message):
    from radtr_addon import cli

    poses = tmp_path / "poses.json"
    poses.write_text('[{"position": [0.3, 0.8, 0.3], "direction": [0, -1, 0]}]')
    monkeypatch.setattr(cli, "open_scene", lambda *a: pytest.fail("the scene was opened"))
    assert cli.main(["flashlight", "cornell_box", "--poses", str(poses), *flags]) == 2
    assert message in capsys.readouterr().err


def test_flashlight_level_beyond_the_hierarchy_is_an_error(cornell, tmp_path):
    from radtr_addon.blender.flashlight import flashlight_for

    job = solve(cornell.context, Settings(levels=1, **FAST), log=quiet)
    with pytest.raises(SettingsError, match=r"low-rank level 3 is not a level of the hierarchy: 0..1"):
        flashlight_for(job, 3, folder=tmp_path)


def test_low_rank_cache_paths_that_are_not_what_they_should_be(tmp_path):
    from geometry import cube

    from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
    from radtr_addon.hierarchy import subdivide
    from radtr_addon.lowrank.cache import cache_key, cached_build

    h = subdivide(cube(), 0.1, 1)
    rows = FormFactors(h.leaves, FormFactorSettings("embree", rays=16))
    (tmp_path / "file").write_text("")
    with pytest.raises(InputFileError, match="the low-rank cache folder .*file is a file"):
        cached_build(h, rows, 1, tmp_path / "file", ff_label=rows.settings.label())
    (tmp_path / f"lowrank-{cache_key(h, 1, rows.settings.label(), np.float64)}.npz").mkdir()
    with pytest.raises(InputFileError, match="the low-rank cache file .*npz is a folder: remove it"):
        cached_build(h, rows, 1, tmp_path, ff_label=rows.settings.label())


# -- results: never garbage, never a false "converged" -------------------------------------------

def test_emission_beyond_what_a_colour_attribute_holds_is_refused(cornell):
    bpy = cornell
    bpy.data.materials["light"].node_tree.nodes["Principled BSDF"].inputs["Emission Strength"].default_value = 2e38
    before = state(bpy)
    with pytest.raises(SceneError, match=r"emission of patch \d+ \(object 'light', material 'light'\): "
                                         r"\(6.28e\+38, .*\) W/m\^2 is NaN or beyond what a colour attribute holds"):
        solve(bpy.context, Settings(**FAST), log=quiet)
    assert state(bpy) == before


def test_non_finite_radiosity_is_never_written(cornell):
    bpy = cornell
    before = state(bpy)
    ctx = bpy.context
    job = SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer, Settings(**FAST), log=quiet).run()
    result = job.solver.result

    def overflowing():
        r = result()
        r.B[7] = [np.inf, 1.0, 1.0]
        return r

    job.solver.result = overflowing
    with pytest.raises(SceneError, match=r"radiosity of patch 7 \(object '\w+', material '\w+'\): \(inf, 1, 1\)"):
        job.finish()
    assert state(bpy) == before


USER_SOLVERS = [
    ("import numpy as np\ndef f(E, **kw):\n    return E * 3.0\n",
     r"returned a B whose residual is [\d.]+ of the emitted power, above the tolerance 0.001"),
    ("import scipy.sparse.linalg as la\nimport numpy as np\n"
     "def f(F, E, rho, areas):\n    return np.stack([E[:, c] + 0j for c in range(3)], axis=1) * (1 + 1j)\n",
     r"returned complex numbers \(largest imaginary part [\d.]+\); return real B"),
    ("import sys\ndef f(**kw):\n    sys.exit(3)\n", r"raised SystemExit: 3 \(bad.py:3\)"),
    ("def f(F, **kw):\n    return F.solve_everything()\n", r"raised AttributeError: .*solve_everything.* \(bad.py:2\)"),
    ("import sys\nsys.exit(1)\n", r"loading it raised SystemExit: 1 \(bad.py:2\)"),
]


@pytest.mark.parametrize("body, message", USER_SOLVERS)
def test_misbehaving_user_solver_is_named_and_changes_nothing(cornell, tmp_path, body, message):
    from radtr_addon.solvers.user import UserSolverError

    bpy = cornell
    (tmp_path / "bad.py").write_text(body)
    before = state(bpy)
    spec = f"{tmp_path / 'bad.py'}:f"
    with pytest.raises(UserSolverError, match=f"user solver '{re.escape(spec)}':? {message}"):
        solve(bpy.context, Settings(solver="user", user_solver=spec, tolerance=1e-3,
                                    **{k: v for k, v in FAST.items() if k != "tolerance"}), log=quiet)
    assert state(bpy) == before


def test_direct_solve_reports_converged_only_when_the_residual_says_so(cornell):
    job = solve(cornell.context, Settings(solver="direct", **FAST), log=quiet)
    assert job.result.converged and job.result.residual <= 1e-2
    assert "converged" in job.summary() and "NOT" not in job.summary()


def test_ctrl_c_in_a_user_solver_ends_the_cli_with_a_line_not_a_traceback(blend, tmp_path, capsys):
    from radtr_addon.cli import main

    (tmp_path / "bad.py").write_text("def f(**kw):\n    raise KeyboardInterrupt\n")
    args = ["solve", "cornell_box", "--max-area", "0.01", "--method", "embree", "--rays", "16",
            "--solver", "user", "--user-solver", f"{tmp_path / 'bad.py'}:f", "--out", str(tmp_path / "r.blend")]
    assert main(args) == 130
    assert capsys.readouterr().err == "RadTR: cancelled\n"
    assert not (tmp_path / "r.blend").exists()


# -- bad input files ---------------------------------------------------------------------------

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"


def write(path, text: str | bytes):
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    return path


def test_nan_vertex_in_a_mesh_names_the_object(cornell):
    bpy = cornell
    bpy.data.objects["tall_block"].data.vertices[3].co = (float("nan"), 0, 0)
    before = state(bpy)
    with pytest.raises(SceneError, match=r"object 'tall_block': vertex \d+ has a NaN or infinite coordinate "
                                         r"\(1 vertices in all"):
        solve(bpy.context, Settings(**FAST), log=quiet)
    assert state(bpy) == before


@pytest.mark.parametrize("line", ["v 1 nan 0", "v 0 1 inf", "v 0 -inf 1", "v 0 one 1"])
def test_obj_vertex_that_is_not_a_finite_number_is_refused_with_file_and_line(blend, tmp_path, line):
    from radtr_addon.blender.objfile import load_obj

    obj = write(tmp_path / "bad.obj", f"{TRIANGLE}{line}\nf 1 2 3\nf 1 2 5\n")
    with pytest.raises(InputFileError, match=f"bad.obj:5: vertex 5 has coordinates {line[2:]}; every coordinate "
                                             f"must be a finite number"):
        load_obj(obj)
    assert not blend.data.objects and not blend.data.meshes


def mtl_scene(tmp_path, mtl: str, obj_prefix: bytes = b""):
    write(tmp_path / "m.mtl", mtl)
    return write(tmp_path / "box.obj", obj_prefix + f"mtllib m.mtl\n{TRIANGLE}usemtl lamp\nf 1 2 3\n"
                                                    f"usemtl wall\nf 1 3 4\nf 1 4 2\n".encode())


def test_invalid_kd_is_a_warning_naming_the_material(blend, tmp_path):
    from radtr_addon.blender.objfile import load_obj

    warnings = load_obj(mtl_scene(tmp_path, "newmtl lamp\nKe 5 5 5\nnewmtl wall\nKd grey 0.5 0.5\n"))
    assert "m.mtl:4: material 'wall': Kd grey 0.5 0.5 is not three numbers; Blender's default is used" in warnings
    warnings = load_obj(mtl_scene(tmp_path, "newmtl lamp\nKe 5 5 5\nnewmtl wall\nKd 1.5 0.5 -0.1\n"))
    assert any("material 'wall': Kd 1.5 0.5 -0.1 is outside 0..1" in w for w in warnings)


@pytest.mark.parametrize("ke, why", [("nan 1 1", "is not a finite emission"),
                                     ("5 -1 5", "is negative; emission must be 0 or more")])
def test_bad_ke_is_refused_naming_the_material(blend, tmp_path, ke, why):
    from radtr_addon.blender.objfile import load_obj

    with pytest.raises(InputFileError, match=f"m.mtl:2: material 'lamp': Ke {ke} {why}"):
        load_obj(mtl_scene(tmp_path, f"newmtl lamp\nKe {ke}\nnewmtl wall\nKd 0.5 0.5 0.5\n"))
    assert not blend.data.objects


def test_mtl_reference_after_a_utf8_bom_is_honoured(blend, tmp_path):
    from radtr_addon.blender.objfile import load_obj

    warnings = load_obj(mtl_scene(tmp_path, "newmtl lamp\nKa 4 4 4\nnewmtl wall\nKd 0.5 0.5 0.5\n",
                                  b"\xef\xbb\xbf"))
    assert any("material 'lamp': Ka (4.0, 4.0, 4.0) taken as emitted radiance" in w for w in warnings)
    lamp = blend.data.materials["lamp"].node_tree.nodes["Principled BSDF"]
    assert lamp.inputs["Emission Strength"].default_value == 4.0


@pytest.mark.parametrize("kind", ["random", "truncated", "empty"])
def test_unreadable_blend_files_are_an_input_file_error(cornell, tmp_path, kind):
    import os

    from radtr_addon.blender.scenes import open_scene

    bpy = cornell
    good = tmp_path / "good.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(good), copy=True)
    data = good.read_bytes()
    body = {"random": os.urandom(4096), "truncated": data[:len(data) // 2], "empty": b""}[kind]
    bad = write(tmp_path / "bad.blend", body)
    before = state(bpy)
    with pytest.raises(InputFileError, match=r"bad.blend: not a .blend file Blender can read \(.+\)"):
        open_scene(str(bad))
    assert state(bpy) == before


# -- extreme scales ------------------------------------------------------------------------------

def furnace(emission: float, size: float):
    """A closed cube of side ``size`` about the origin, reflectance 0.5, emitting ``emission``:
    B = 2 emission, in the area mean exactly."""
    from geometry import cube

    from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
    from radtr_addon.hierarchy import subdivide
    from radtr_addon.scene import PatchScene
    from radtr_addon.solvers import solve as solve_scene

    c = cube()
    scene = PatchScene((c.vertices - 0.5) * size, c.triangles, 0.5, emission, 0, 0)
    leaves = subdivide(scene, 0.05 * size ** 2, 1).leaves
    r = solve_scene("shooting", leaves, FormFactors(leaves, FormFactorSettings("embree", rays=64)), tol=1e-4)
    return r, leaves.areas


@pytest.mark.parametrize("emission, size", [(1e16, 1.0), (1e-16, 1.0), (1.0, 1e16), (1.0, 1e-16), (1.0, 1e12)])
def test_white_furnace_is_right_at_any_emission_and_any_size(emission, size):
    unit, _ = furnace(1.0, 1.0)
    r, areas = furnace(emission, size)
    assert r.converged and r.escaped.max() == 0
    assert np.average(r.B[:, 0], weights=areas) / emission == pytest.approx(2.0, rel=2e-4)
    np.testing.assert_allclose(r.B / emission, unit.B, rtol=1e-6)


# -- huge work refused before it starts ----------------------------------------------------------

def test_subdivision_over_the_memory_budget_is_refused_with_the_size():
    """3,145,728 patches (under the 4 M cap) for a shooting solve: refused before any work."""
    from geometry import cube

    from radtr_addon.hierarchy import MAX_PATCHES, check_patch_memory, estimate_leaf_count, subdivide
    from radtr_addon.solvers import patch_bytes

    c = cube()
    max_area = 0.5 / 4 ** 9
    assert estimate_leaf_count(c.areas, max_area, 1) == 12 * 4 ** 9 < MAX_PATCHES
    with pytest.raises(SettingsError, match=r"would make 3,145,728 patches, and a shooting solve of them needs "
                                            r"6.00 GiB \(2,048 bytes a patch\), over the memory budget of 2,048 MB: "
                                            r"raise the budget \(Memory Budget, --cache-mb\) to 6,144 MB"):
        subdivide(c, max_area, 1, budget_bytes=2048 << 20, bytes_per_patch=patch_bytes("shooting"),
                  what="a shooting solve")
    with pytest.raises(SettingsError, match=r"a direct solve of them needs 15.00 GiB \(5,120 bytes a patch\)"):
        check_patch_memory(12 * 4 ** 9, max_area, 1, 2048 << 20, patch_bytes("direct"), "a direct solve")
    check_patch_memory(12 * 4 ** 9, max_area, 1, 6144 << 20, patch_bytes("shooting"))   # raised: accepted
    assert subdivide(c, 0.5 / 4 ** 3, 1, budget_bytes=2048 << 20).leaves.n == 12 * 4 ** 3


def sparse_rows(n: int, per_row: int):
    """A row cache over n patches whose rows each see ``per_row`` others (computed on demand)."""
    from radtr_addon.formfactors.rows import Row, RowCache

    def compute(ids):
        rng = np.random.default_rng(0)
        return [Row(np.sort(rng.choice(n, per_row, replace=False)), np.full(per_row, 0.5 / per_row), 0.5, 0.0)
                for _ in ids]
    return RowCache(compute, 64 << 30)


def test_direct_solve_of_many_patches_is_refused_before_assembling():
    from geometry import cube

    from radtr_addon.scene import PatchScene
    from radtr_addon.solvers import make_solver

    n = 20_000
    c = cube()
    scene = PatchScene(np.tile(c.vertices[c.triangles[0]], (n, 1)), np.arange(3 * n).reshape(n, 3), 0.5, 1.0, 0, 0)
    rows = sparse_rows(n, 20)
    with pytest.raises(SceneError, match=r"the direct solve of 20,000 patches would take about [\d.]+ (min|h) "
                                         r"\(assembling 20,000 form-factor rows [\d.]+ s, LU of about 2.3e\+08 "
                                         r"non-zeros a channel [\d.]+ (min|h)\), over the limit of 10.0 min: use an "
                                         r"iterative solver \(shooting, jacobi or gauss_seidel\), or fewer patches"):
        make_solver("direct", scene, rows)
    assert rows.computed == 64                  # only the size sample: nothing assembled
    make_solver("shooting", scene, rows)        # the iterative solvers take it


# -- watch mode ----------------------------------------------------------------------------------

def test_watch_skips_a_file_cut_inside_its_last_number(cornell, tmp_path):
    from radtr_addon.blender.flashlight import LiveMeshes
    from radtr_addon.blender.sequence import watch
    from radtr_addon.exchange import load_vector

    job = solve(cornell.context, Settings(solver="direct", **FAST), log=quiet)
    E = job.leaves.emission
    target = tmp_path / "live_es.dat"
    np.savetxt(target, 2 * E + 0.123456, fmt="%.6f")
    full = target.read_text()
    cut = full[:-4]                                      # inside the last number: right row count
    assert load_vector(write(tmp_path / "cut.dat", cut), job.leaves.n).shape == E.shape
    target.write_text(cut)
    before = [b.copy() for pair in LiveMeshes(job.objects, job.leaves).snapshot() for b in pair]
    logs = []
    script = iter([quiet, quiet, quiet, lambda: target.write_text(full), quiet, quiet])
    shown = watch(job, target, tmp_path / "w", polls=6, sleep=lambda _: next(script)(), log=logs.append)
    assert [p.name for p in shown] == ["watch_0000.png"]                # only the complete version
    skipped = [line for line in logs if "no line end" in line]
    assert len(skipped) == 1 and skipped[0] == (               # tried again every poll, said once
        f"RadTR warning: {target}: its last line has no line end (cut inside its last number?); skipped, "
        f"waiting for a complete file (looking again every 0.5 s)")
    after = [b.copy() for pair in LiveMeshes(job.objects, job.leaves).snapshot() for b in pair]
    assert all(np.array_equal(a, b) for a, b in zip(after, before))   # colours restored


# -- coincident back-to-back faces ---------------------------------------------------------------

def doubled_box(other_diagonal: bool = False):
    """The unit cube facing in (object 'room') with every wall doubled by a face facing out
    ('shell'): the same corners, or the quads split along their other diagonal."""
    from geometry import cube

    from radtr_addon.scene import PatchScene

    c = cube()
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    if other_diagonal:
        out = [[d, b, a] for a, b, _, d in quads] + [[d, c_, b] for _, b, c_, d in quads]
    else:
        out = c.triangles[:, ::-1]
    return PatchScene(c.vertices, np.concatenate([c.triangles, out]), 0.5, 1.0, [0] * 12 + [1] * 12, 0,
                      ["room", "shell"], ["wall"])


@pytest.mark.parametrize("other_diagonal", [False, True])
def test_faces_modelled_twice_are_named_and_faces_resting_on_faces_are_not(other_diagonal):
    """The doubled box's walls, the same corners facing away, are named (192 pairs of leaves
    at 0.05); split along the other diagonal each outer triangle rests across two inner ones,
    as a box rests on a floor: a contact, not a duplicate, so nothing is said."""
    from radtr_addon.formfactors.coincident import twins
    from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
    from radtr_addon.hierarchy import subdivide

    leaves = subdivide(doubled_box(other_diagonal), 0.05, 1).leaves
    twin = twins(leaves.vertices, leaves.triangles, leaves.normals)
    has = np.flatnonzero(twin >= 0)
    assert len(has) == (0 if other_diagonal else 2 * 192)
    assert np.all(twin[twin[has]] == has) and np.allclose(leaves.normals[has], -leaves.normals[twin[has]])
    assert np.all(leaves.object_index[has] != leaves.object_index[twin[has]])      # each wall's inner and outer face
    ff = FormFactors(leaves, FormFactorSettings("embree", rays=16))
    assert ff.warnings == ([] if other_diagonal else [
        "192 faces modelled twice, back to back (the same corners facing away from each other), in 'room' and "
        "'shell': each side is lit from its front only, as the two sides of an opaque sheet are; if one of each "
        "pair is a duplicate, delete it (it costs its own patches)"])
    single = subdivide(doubled_box().subset(np.arange(24) < 12), 0.05, 1).leaves
    assert FormFactors(single, FormFactorSettings("embree", rays=16)).warnings == []


@pytest.mark.parametrize("method, rel", [("hemicube", 1e-9), ("paraboloid", 6e-3), ("embree", 1e-9)])
def test_white_furnace_with_doubled_walls_is_right_with_every_method(gpu, method, rel):
    """Each inward face sees only inward faces (row sum 1) and the shooting solve gives the
    furnace's B = E / (1 - rho) = 2; the GPU methods used to see the outward twins' backs."""
    from radtr_addon.formfactors.methods import FormFactors, FormFactorSettings
    from radtr_addon.hierarchy import subdivide
    from radtr_addon.solvers import solve as solve_scene

    leaves = subdivide(doubled_box(), 0.02, 1).leaves
    room = leaves.object_index == 0
    leaves.emission[~room] = 0.0
    ff = FormFactors(leaves, FormFactorSettings(method, resolution=64, rays=64), fallback=False)
    rows = ff.rows(np.flatnonzero(room))
    assert np.mean([r.values[room[r.indices]].sum() for r in rows]) == pytest.approx(1.0, rel=rel)
    blocked = [r.blocked for r in rows]                      # 0.98 (hemicube), 0.77 (paraboloid) before
    assert np.mean(blocked) < 1e-3 and max(blocked) < 1e-2
    r = solve_scene("shooting", leaves, ff, tol=1e-4)
    B = np.average(r.B[room, 0], weights=leaves.areas[room])
    assert B == pytest.approx(2.0, rel=2 * rel / 0.5 + 1e-4)


# -- a user solver that never returns --------------------------------------------------------------

def test_user_solver_that_never_returns_can_be_cancelled(cornell, tmp_path):
    """Each step hands control back while the function runs (the panel's Esc drops the job,
    Ctrl-C ends the CLI); the scene is unchanged."""
    import time

    (tmp_path / "stuck.py").write_text("import threading\ngate = threading.Event()\n"
                                       "def f(E, **kw):\n    gate.wait()\n    return E\n")
    bpy = cornell
    before = state(bpy)
    ctx = bpy.context
    spec = f"{tmp_path / 'stuck.py'}:f"
    job = SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer,
                   Settings(solver="user", user_solver=spec, **FAST), log=quiet)
    solver = job.solver
    t0 = time.perf_counter()
    while solver._worker is None:
        solver.step(1)                                     # assembling
    for _ in range(5):
        t1 = time.perf_counter()
        assert job.advance(0.05) is False                  # the modal operator's tick returns ...
        assert time.perf_counter() - t1 < 0.5              # ... at once, though the function does not
    assert time.perf_counter() - t0 < 30
    assert re.fullmatch(rf"user solver '{re.escape(spec)}' running for \d+ s", solver.phase)
    del job                                                # cancel: drop the job
    assert state(bpy) == before
    solver.function.__globals__["gate"].set()              # let the abandoned thread end
    assert solver._worker.wait(5)


def test_click_operators_end_cleanly_on_esc_and_on_an_error(addon, monkeypatch):
    """Toggle Patch Emission and Pick Patch View share ``ClickPatches``: Esc ends with the header
    cleared; a click whose work raises ends with the reason reported and the header cleared."""
    import radtr.operators.session as op

    headers, reports = [], []
    context = SimpleNamespace(area=SimpleNamespace(header_text_set=headers.append))
    monkeypatch.setattr(op, "mouse_ray", lambda ctx, ev: ((0, 0, 0), (0, 0, -1)))

    def fails(ctx, origin, direction):
        raise ZeroDivisionError("division by zero")

    clicker = SimpleNamespace(clicked=fails, report=lambda kind, msg: reports.append((kind, msg)))
    press = SimpleNamespace(type="LEFTMOUSE", value="PRESS")
    assert op.ClickPatches.modal(clicker, context, SimpleNamespace(type="MOUSEMOVE", value="")) == {"PASS_THROUGH"}
    assert op.ClickPatches.modal(clicker, context, press) == {"CANCELLED"}
    assert headers == [None] and reports[0][0] == {"ERROR"} and "ZeroDivisionError" in reports[0][1]
    clicker.clicked = lambda ctx, origin, direction: False
    assert op.ClickPatches.modal(clicker, context, press) == {"RUNNING_MODAL"}
    assert op.ClickPatches.modal(clicker, context, SimpleNamespace(type="ESC", value="PRESS")) == {"FINISHED"}
    assert headers == [None, None]
