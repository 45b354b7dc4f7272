"""One settings schema: the CLI flags are built from ``Settings`` and the Scene's RadTR
properties are checked against it (name, default, choices) and copied from it field by field."""
import argparse
from dataclasses import fields

import pytest

from radtr_addon.formfactors.methods import FormFactorSettings
from radtr_addon.settings import Settings, add_arguments


def parser():
    p = argparse.ArgumentParser()
    add_arguments(p)
    return p


def test_cli_defaults_are_the_schema_defaults():
    assert Settings.of(parser().parse_args([])) == Settings()


def test_cli_flags_set_every_field():
    args = parser().parse_args(["--max-area", "0.5", "--levels", "3", "--method", "paraboloid", "--resolution", "32",
                                "--rotate", "--split", "uniform", "--iterations", "7", "--solver", "hierarchical",
                                "--precision", "float32", "--sky", "cie", "--mode", "REPLACE", "--cache-mb", "64"])
    s = Settings.of(args)
    assert (s.max_area, s.levels, s.method, s.resolution, s.rotate, s.split, s.max_iterations, s.solver,
            s.precision, s.sky, s.mode, s.cache_mb) == (0.5, 3, "paraboloid", 32, True, "uniform", 7,
                                                        "hierarchical", "float32", "cie", "REPLACE", 64)


def test_cli_refuses_a_choice_outside_the_schema(capsys):
    with pytest.raises(SystemExit):
        parser().parse_args(["--method", "raytracing"])
    assert "invalid choice" in capsys.readouterr().err


def test_settings_refuse_a_choice_outside_the_schema():
    from radtr_addon.errors import SettingsError

    with pytest.raises(SettingsError, match="solver must be one of shooting"):
        Settings(solver="gauss").validate()


def test_form_factor_defaults_are_one():
    ff, s = FormFactorSettings(), Settings()
    assert (ff.method, ff.resolution, ff.rotate, ff.split, ff.split_level, ff.rays) == (
        s.method, s.resolution, s.rotate, s.split, s.split_level, s.rays)
    assert s.form_factors() == ff


def test_blender_properties_follow_the_schema(blend):
    props = blend.context.scene.radtr
    rna = props.bl_rna.properties
    for f in fields(Settings):
        assert f.name in rna, f"no Scene property for setting '{f.name}'"
        prop = rna[f.name]
        if f.metadata["choices"]:
            assert {item.identifier for item in prop.enum_items} == set(f.metadata["choices"]), f.name
        default = prop.default
        assert default == (pytest.approx(f.default, rel=1e-6) if isinstance(default, float) else f.default), f.name


def test_to_settings_copies_every_field(blend):
    props = blend.context.scene.radtr
    changed = dict(max_area=0.5, levels=3, method="embree", resolution=33, rotate=True, split="none",
                   split_level=7, rays=99, solver="jacobi", quality=0.2, user_solver="m:f", tolerance=0.01,
                   max_iterations=5, precision="float32", ambient=True, gather_rays=16, sky="uniform",
                   sky_radiance=2.0, sky_step=15.0, sky_altitude_step=5.0, sky_resolution=64, max_reflectance=0.5,
                   exposure=2.0, mode="REPLACE", cache_mb=99, scheduler="local:2")
    assert set(changed) == {f.name for f in fields(Settings)}
    for name, value in changed.items():
        setattr(props, name, value)
    got = props.to_settings()
    for name, value in changed.items():
        expected = value - value % 2 if name == "resolution" else value     # the hemicube's even count
        assert getattr(got, name) == pytest.approx(expected), name
