"""Long research tasks as steps: generators that yield the fraction done (0..1) and return
their result. The CLI runs them to the end (``run``); the operators advance them from a timer,
with a progress bar and ESC (closing a generator runs its ``finally``: nothing half-done stays).

``export_steps`` writes a solve's matrices (F, the low-rank U and V of a level or of a refined
multi-level cut, the sky matrix and its points) in the formats of ``exchange``; ``sky_steps``
computes the sky form factors of a solve's patches (and one picture a dome point on request).
"""
from __future__ import annotations

from pathlib import Path

from .errors import Cancelled, SettingsError


def run(steps, progress=None):
    """Advance ``steps`` to the end and return its result; ``progress(fraction)`` after each
    step may return False to cancel (the generator is closed, Cancelled raised)."""
    try:
        while True:
            fraction = next(steps)
            if progress is not None and progress(fraction) is False:
                steps.close()
                raise Cancelled("cancelled; nothing was written")
    except StopIteration as done:
        return done.value


def export_target(path) -> Path:
    """``path`` checked before any work: .npz, .mat, or a prefix for the seed's .dat files, in a folder that exists."""
    path = Path(path)
    if path.suffix not in ("", ".npz", ".mat"):
        raise SettingsError(f"{path}: export writes .npz, .mat or the seed's text files (a prefix with no suffix)")
    if not path.resolve().parent.is_dir():
        raise SettingsError(f"{path}: the folder {path.resolve().parent} does not exist")
    return path


def export_steps(solve, path, level: int | None = None, refine_to: int = 0, sky=None, log=print):
    """Write the form factors of ``solve`` (a uniform ``pipeline.Solve``), its emission,
    reflectance, areas and triangles, the low-rank U and V of hierarchy ``level`` (refined to
    ``refine_to`` clusters where the light is, several levels combined), and ``sky`` (a
    SkyFactors: the matrix, directions, positions and solid angles) to ``path``. Yields the
    fraction done, returns the files written."""
    from .exchange import arrays_of, export
    from .solvers.matrix import Assembly

    path = export_target(path)
    if solve.rows is None:
        raise SettingsError("export needs the form factors of a uniform solve; the hierarchical solver keeps none")
    if level is not None and not 0 <= level <= solve.hierarchy.levels:
        raise SettingsError(f"low-rank level {level} is not a level of the hierarchy: 0..{solve.hierarchy.levels}")
    if level is not None and level == solve.hierarchy.levels and refine_to <= solve.leaves.n:
        log(f"RadTR warning: low-rank level {level} is the leaf level: U is {solve.leaves.n:,} x {solve.leaves.n:,} "
            f"dense, no smaller than F; solve with more --levels (Levels) for clusters")
    assembly = Assembly(solve.rows, solve.leaves.n)
    F = None
    share = 0.8 if level is not None else 1.0
    while F is None:
        F = assembly.step()
        yield share * assembly.cursor / solve.leaves.n
    U = V = None
    if level is not None:
        from .lowrank import build, build_cut, refined_cut

        hierarchy = solve.hierarchy
        if refine_to > len(hierarchy.representative[level]):
            lowrank = build_cut(hierarchy, solve.rows, refined_cut(hierarchy, solve.rows, level, refine_to))
        else:
            lowrank = build(hierarchy, solve.rows, level)
        U, V = lowrank.U, lowrank.V
        yield 0.95
    return export(path, arrays_of(solve.leaves, F, U, V, sky))


def scaled(steps, start: float, share: float):
    """``steps`` with its fractions mapped onto start..start + share (``x = yield from scaled(...)``
    runs a task inside another); returns its result."""
    while True:
        try:
            fraction = next(steps)
        except StopIteration as done:
            return done.value
        yield start + share * fraction


def sky_steps(scene, alpha: float, beta: float, resolution: int, image_dir=None, image_resolution: int = 128,
              scheduler: str = ""):
    """Sky form factors of ``scene`` (``sky.sky_factor_steps``, on the Dask cluster ``scheduler``
    names if any) and, with ``image_dir``, one PNG a dome point (``sky.sky_image_steps``).
    Yields the fraction done; returns (SkyFactors, PNG paths)."""
    from .sky import sky_factor_steps, sky_image_steps

    share = 0.5 if image_dir else 1.0
    sky = yield from scaled(sky_factor_steps(scene, alpha, beta, resolution, scheduler), 0.0, share)
    paths = []
    if image_dir:
        paths = yield from scaled(sky_image_steps(scene, sky, image_dir, image_resolution), share, share)
    return sky, paths
