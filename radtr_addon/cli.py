"""Command line: ``python -m radtr_addon solve SCENE ...`` and ``... bench NAME``.

SCENE is a .blend file, a scene file Blender imports (.obj, .ply, .stl, .gltf/.glb, .fbx,
.usd*, .abc: Blender's own importers) or the name of a bundled scene in ``scenes/`` (e.g.
``cornell_box``). Runs on the PyPI ``bpy`` module; the
same solve runs inside Blender as ``bpy.ops.radtr.solve()``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .blender.scenes import open_scene
from .errors import RadTRError, SettingsError, user_message
from .lowrank.backends import BACKENDS, DEFAULT_BACKEND
from .settings import add_arguments

SCENE_HELP = ".blend, .obj, .ply, .stl, .gltf, .glb, .fbx, .usd(a/c/z), .abc or a bundled scene name"


def settings_from(args):
    from .settings import Settings

    return Settings.of(args)


def check_args(args):
    """Settings, flashlight level and output paths checked before any work."""
    if not hasattr(args, "levels"):
        return
    settings_from(args).validate()
    level = getattr(args, "level", None)
    if level is not None and not 0 <= level <= args.levels:
        raise SettingsError(f"--level {level} is not a level of the hierarchy: 0..{args.levels} "
                            f"with --levels {args.levels}")
    gltf = getattr(args, "gltf", None)
    if gltf and Path(gltf).suffix.lower() not in (".glb", ".gltf"):
        raise SettingsError(f"--gltf {gltf}: a glTF file ends in .glb or .gltf")
    render = getattr(args, "render", None)
    if render and Path(render).suffix.lower() != ".png":
        raise SettingsError(f"--render {render}: the picture is written as PNG; name it .png")
    if getattr(args, "camera", "") and not render:
        raise SettingsError(f"--camera {args.camera} needs --render (the picture it is for)")
    watched = getattr(args, "file", None)
    if watched and not Path(watched).resolve().parent.is_dir():
        raise SettingsError(f"--file {watched}: the folder {Path(watched).resolve().parent} does not exist")
    for flag in ("out", "render", "gltf"):
        path = getattr(args, flag, None)
        if path and not Path(path).resolve().parent.is_dir():
            raise SettingsError(f"--{flag} {path}: the folder {Path(path).resolve().parent} does not exist")
    if args.command == "export":
        from .tasks import export_target

        export_target(args.out)
    if args.command == "flashlight" and args.solver == "hierarchical":
        raise SettingsError("the flashlight needs the low-rank factors of the uniform patch hierarchy: "
                            "--solver hierarchical makes none (use shooting, jacobi, gauss_seidel or direct)")
    backend = getattr(args, "backend", None)
    if backend is not None and backend != "user" and backend not in BACKENDS:
        raise SettingsError(f"--backend {backend}: the back-ends are {', '.join(BACKENDS)} and user")
    if backend == "user" and not args.user_frame:
        raise SettingsError("--backend user calls your function every frame: name it with "
                            "--user-frame module:function or file.py:function")
    out_dir = getattr(args, "out_dir", None)
    if out_dir and Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise SettingsError(f"--out-dir {out_dir} is a file, not a folder")


def cmd_solve(args) -> int:
    import bpy

    from .blender.pipeline import solve
    from .blender.render import render_png

    for w in open_scene(args.scene):
        print(f"RadTR warning: {w}")
    if args.camera:
        from .blender.render import find_camera

        find_camera(bpy.context.scene, args.camera)          # named before the solve, not after it
    job = solve(bpy.context, settings_from(args), progress=_every(lambda job: print(f"RadTR: {job.readout}")))
    times = ", ".join(f"{k} {v:.2f} s" for k, v in job.stats.seconds.items())
    print(f"RadTR: stages: {times}")
    if args.out:
        bpy.ops.wm.save_as_mainfile(filepath=str(Path(args.out).resolve()))
        print(f"RadTR: wrote {args.out}")
    if args.render:
        render_png(bpy.context.scene, str(Path(args.render).resolve()), camera=args.camera)
        print(f"RadTR: rendered {args.render}")
    if args.gltf:
        from .blender.gltf import export_gltf

        for w in export_gltf(bpy.context.scene, job.objects, args.gltf, job.settings.exposure):
            print(f"RadTR warning: {w}")
        print(f"RadTR: wrote {args.gltf}")
    return 0


def read_poses(path: str) -> list[list[dict]]:
    """Poses from a JSON list, checked before any work: each a spot {position, direction,
    angle_deg, intensity, color} or a non-empty list of spots lighting at once."""
    import json

    import numpy as np

    try:
        entries = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise RadTRError(f"{path}: not a JSON list of poses ({exc})") from None
    if not isinstance(entries, list) or not entries:
        raise RadTRError(f"{path}: no poses (a JSON list of spots, or of lists of spots, is needed)")
    poses = []
    for k, entry in enumerate(entries):
        spots = entry if isinstance(entry, list) else [entry]
        if not spots:
            raise RadTRError(f"{path}: pose {k} is an empty list (give it at least one spot)")
        for j, spot in enumerate(spots):
            where = f"pose {k}" + (f", spot {j}" if isinstance(entry, list) else "")
            try:
                values = np.concatenate([np.asarray(spot[key], float).reshape(3) for key in ("position", "direction")]
                                        + [np.asarray(spot.get("color", (1, 1, 1)), float).reshape(3),
                                           [float(spot.get("angle_deg", 20)), float(spot.get("intensity", 1))]])
            except (KeyError, TypeError, ValueError, AttributeError) as exc:
                raise RadTRError(f"{path}: {where} is not a spot with position and direction "
                                 f"([x, y, z] each): {exc}") from None
            if not np.isfinite(values).all() or values[6:].min() < 0:
                raise RadTRError(f"{path}: {where} has a NaN, infinite or negative value (intensity "
                                 f"{values[-1]:g}, colour {values[6:9].tolist()})")
        poses.append(spots)
    return poses


def spots_for(poses: list[list[dict]], scene) -> list:
    """The Spots of each pose (``read_poses``), lit like the scene's own light
    unless the pose says its intensity."""
    import numpy as np

    from .blender.flashlight import default_spot

    def spot_of(entry):
        spot = default_spot(scene, entry["position"], entry["direction"])
        spot.angle = np.radians(float(entry.get("angle_deg", np.degrees(spot.angle))))
        spot.intensity = float(entry.get("intensity", spot.intensity))
        spot.color = np.asarray(entry.get("color", spot.color), float)
        return spot

    return [[spot_of(e) for e in p] for p in poses]


def cmd_flashlight(args) -> int:
    import bpy

    from .blender.flashlight import flashlight_for, render_poses
    from .blender.pipeline import solve

    poses = read_poses(args.poses)                  # checked before the solve and the precompute
    for w in open_scene(args.scene):
        print(f"RadTR warning: {w}")
    job = solve(bpy.context, settings_from(args))
    light, meshes, warnings, hit = flashlight_for(job, args.level, args.backend,
                                                  Path(args.out_dir) / "lowrank-cache", args.refine_to,
                                                  args.user_frame)
    for w in warnings:
        print(f"RadTR warning: {w}")
    print(f"RadTR: low-rank {light.lowrank.k:,} clusters "
          f"{'read from the cache' if hit else 'built'}; frames on the {light.backend_name} back-end")
    for path in render_poses(bpy.context.scene, light, meshes, spots_for(poses, job.leaves), args.out_dir):
        print(f"RadTR: rendered {path}")
    return 0


def cmd_export(args) -> int:
    import bpy

    from .blender.pipeline import SolveJob
    from .tasks import export_steps, run

    for w in open_scene(args.scene):
        print(f"RadTR warning: {w}")
    ctx = bpy.context
    job = SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer, settings_from(args))
    steps = export_steps(job, args.out, args.level, args.refine_to, job.sky)
    for path in run(steps, progress=_every(lambda f: print(f"RadTR: export {f:.0%}"))):
        print(f"RadTR: wrote {path}")
    return 0


def _every(show, seconds: float = 2.0):
    """A ``progress(x)`` that calls ``show(x)`` at most every ``seconds`` (a line a while, not a flood)."""
    import time

    last = [time.perf_counter()]

    def progress(x):
        if time.perf_counter() - last[0] >= seconds:
            last[0] = time.perf_counter()
            show(x)
            sys.stdout.flush()
    return progress


def cmd_sequence(args) -> int:
    import bpy

    from .blender.pipeline import SolveJob
    from .blender.sequence import render_sequence, watch
    from .exchange import load_vector

    for w in open_scene(args.scene):
        print(f"RadTR warning: {w}")
    ctx = bpy.context
    job = SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer, settings_from(args))
    if args.command == "sequence":                 # every file checked against the patches before the solve
        for i in range(args.first, args.last + 1):
            load_vector(f"{args.prefix}{i}{args.suffix}", job.leaves.n)
    job.run()
    job.finish()
    if args.command == "watch":
        print(f"RadTR: watching {args.file} every {args.interval:g} s (Ctrl+C stops)", flush=True)
        paths = watch(job, args.file, args.out_dir, args.polls, args.interval, out_prefix=args.out_prefix)
    else:
        paths = render_sequence(job, args.prefix, args.first, args.last, args.out_dir, args.suffix, args.out_prefix)
    for path in paths:
        print(f"RadTR: rendered {path}")
    return 0


def cmd_backends(args) -> int:
    """Each low-rank back-end (or those named) and whether it runs here (the OpenCL ones: on
    which device, or why not); 1 when one cannot run."""
    from .lowrank.backends import opencl_device, unavailable

    names = args.names or list(BACKENDS)
    unknown = sorted(set(names) - set(BACKENDS))
    if unknown:
        raise SettingsError(f"no back-end named {', '.join(unknown)}: they are {', '.join(BACKENDS)}")
    for name in names:
        cls = BACKENDS[name]
        reason = unavailable(name)
        device = opencl_device(cls.source)[0] if reason is None and hasattr(cls, "source") else None
        where = f" on {device.platform.name} {device.name.strip()}" if device is not None else ""
        print(f"{name}: " + (f"unavailable: {reason}" if reason else f"available{where}"))
    return int(any(unavailable(name) for name in names))


def cmd_bench(args) -> int:
    from .bench import run_benchmark

    return run_benchmark(args.name, quick=args.quick, json_path=args.json)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m radtr_addon", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    shown = argparse.ArgumentDefaultsHelpFormatter          # --help gives each flag's default
    p = sub.add_parser("solve", formatter_class=shown, help="solve a scene and write the result")
    p.add_argument("scene", help=SCENE_HELP)
    p.add_argument("--out", help="write the solved scene to this .blend")
    p.add_argument("--render", help="render the solved scene to this PNG")
    p.add_argument("--camera", default="", help="with --render: the camera object to render through "
                                                "(default: the scene's, else a view from the front)")
    p.add_argument("--gltf", help="write the result meshes to this .glb/.gltf (COLOR_0: the radiance shown; "
                                  "_RADTR_RADIOSITY: B)")
    add_arguments(p)
    p.set_defaults(func=cmd_solve)
    f = sub.add_parser("flashlight", formatter_class=shown,
                       help="solve, then render one PNG per flashlight pose (low-rank)")
    f.add_argument("scene", help=SCENE_HELP)
    f.add_argument("--poses", required=True,
                   help="JSON list of poses: {position, direction, angle_deg, intensity, color}, or a list of "
                        "them lighting at once")
    f.add_argument("--out-dir", default="out/flashlight", help="folder for the PNGs and the low-rank cache")
    f.add_argument("--level", type=int, default=1, help="hierarchy level of the low-rank clusters")
    f.add_argument("--refine-to", type=int, default=0,
                   help="refine the level's clusters where the light is until there are this many")
    f.add_argument("--backend", default=DEFAULT_BACKEND,
                   help=f"low-rank back-end: {', '.join(BACKENDS)} (-int8: 8-bit U) or user; "
                        "`backends` says which run here")
    f.add_argument("--user-frame", default="", help="with --backend user: module:function called every frame")
    add_arguments(f)
    f.set_defaults(func=cmd_flashlight)
    e = sub.add_parser("export", formatter_class=shown,
                       help="write form factors, emission, reflectance, areas, triangles (and U, V; "
                            "with --sky the sky matrix and its points)")
    e.add_argument("scene", help=SCENE_HELP)
    e.add_argument("--out", required=True, help="file.npz, file.mat, or a prefix for the seed's .dat files")
    e.add_argument("--level", type=int, help="also the low-rank U and V of this hierarchy level")
    e.add_argument("--refine-to", type=int, default=0,
                   help="with --level: refine the level's clusters where the light is until there are this many "
                        "(the multi-level cut)")
    add_arguments(e)
    e.set_defaults(func=cmd_export)
    q = sub.add_parser("sequence", formatter_class=shown,
                       help="solve and render emission files <prefix><i><suffix>, i = from..to")
    q.add_argument("scene", help=SCENE_HELP)
    q.add_argument("--prefix", required=True)
    q.add_argument("--suffix", default="", help="e.g. .dat")
    q.add_argument("--from", dest="first", type=int, default=1)
    q.add_argument("--to", dest="last", type=int, required=True)
    q.add_argument("--out-dir", default="out/sequence")
    q.add_argument("--out-prefix", default="frame_", help="PNG names: <out-prefix><i, 4 digits>.png")
    add_arguments(q)
    q.set_defaults(func=cmd_sequence)
    w = sub.add_parser("watch", formatter_class=shown,
                       help="solve and render an emission file each time another program rewrites it")
    w.add_argument("scene", help=SCENE_HELP)
    w.add_argument("--file", required=True)
    w.add_argument("--out-dir", default="out/watch")
    w.add_argument("--out-prefix", default="watch_", help="PNG names: <out-prefix>NNNN.png")
    w.add_argument("--polls", type=int, default=1_000_000, help="how many times to look (Ctrl+C stops)")
    w.add_argument("--interval", type=float, default=0.5, help="seconds between looks")
    add_arguments(w)
    w.set_defaults(func=cmd_sequence)
    k = sub.add_parser("backends", help="list the low-rank back-ends and whether each runs on this machine")
    k.add_argument("names", nargs="*", help="only these (exit status 1 when one cannot run)")
    k.set_defaults(func=cmd_backends)
    b = sub.add_parser("bench", formatter_class=shown, help="run a benchmark and print its table")
    b.add_argument("name", help="benchmark name, e.g. skeleton")
    b.add_argument("--quick", action="store_true", help="smaller sizes, for a quick look")
    b.add_argument("--json", help="also write the results to this JSON file")
    b.set_defaults(func=cmd_bench)
    args = parser.parse_args(argv)
    try:
        check_args(args)
        return args.func(args)
    except KeyboardInterrupt:
        print("RadTR: cancelled", file=sys.stderr)
        return 130
    except Exception as exc:
        print(f"RadTR error: {user_message(exc)}", file=sys.stderr)
        return 2
