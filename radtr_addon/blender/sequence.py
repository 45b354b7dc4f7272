"""Emission vectors from files, solved and rendered: numbered sequences and a watched file.

A vector file holds one emission per patch of the solve it was written for (same scene and
settings, hence the same patches: ``exchange``), and is checked by ``exchange.load_vector``.
Each is solved with the job's solver and form factors (``Solve.with_emission``) (rows computed once, then cached), shown
in the result meshes and rendered to a PNG; the meshes' colours are restored afterwards.
``watch`` reloads a file whenever another program rewrites it: a new version is read only when
its size and time stamp have stayed the same for one polling interval, a text file ends with
a line end (a writer stalled inside its last number leaves the right row count), the file did
not change while it was read, and it parses whole as the expected count of finite numbers;
otherwise it is skipped with a warning and tried again the next interval.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..errors import InputFileError
from ..exchange import load_vector
from .flashlight import LiveMeshes
from .render import render_png


def _show(job, meshes, E, png: Path) -> Path:
    meshes.write(job.with_emission(E))
    render_png(job.bl_scene, str(png.resolve()))
    return png


def render_sequence(job, prefix: str, first: int, last: int, out_dir, suffix: str = "",
                    out_prefix: str = "frame_") -> list[Path]:
    """One PNG per file ``<prefix><i><suffix>``, i = first..last (``sequence_steps`` run to the end)."""
    from ..tasks import run

    return run(sequence_steps(job, prefix, first, last, out_dir, suffix, out_prefix))


def sequence_steps(job, prefix: str, first: int, last: int, out_dir, suffix: str = "", out_prefix: str = "frame_"):
    """``render_sequence`` as steps (``tasks``): every file is checked first, then one PNG
    ``<out_prefix><i>.png`` a step; the meshes' colours are restored when done or closed."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    vectors = [(i, load_vector(f"{prefix}{i}{suffix}", job.leaves.n)) for i in range(first, last + 1)]
    meshes = LiveMeshes(job.objects, job.leaves)
    saved = meshes.snapshot()
    paths = []
    try:
        for i, E in vectors:
            paths.append(_show(job, meshes, E, out_dir / f"{out_prefix}{i:04d}.png"))
            yield len(paths) / len(vectors)
    finally:
        meshes.restore(saved)
    return paths


def read_complete(path: Path, n: int) -> np.ndarray:
    """E (n, 3) from ``path`` if it is complete (see the module docstring), else InputFileError."""
    def signature():
        st = path.stat()
        return st.st_mtime_ns, st.st_size

    before = signature()
    if path.suffix not in (".npz", ".mat"):
        with open(path, "rb") as f:
            f.seek(max(before[1] - 1, 0))
            if f.read(1) not in (b"\n", b"\r"):
                raise InputFileError(f"{path}: its last line has no line end (cut inside its last number?)")
    E = load_vector(path, n)
    if signature() != before:
        raise InputFileError(f"{path}: changed while it was read")
    return E


class Watcher:
    """Polls an emission file; each complete new version is solved, shown and rendered to
    ``<out_prefix>NNNN.png``. ``close`` restores the meshes' colours."""

    def __init__(self, job, path, out_dir, out_prefix: str = "watch_", log=print):
        self.job, self.path, self.out_dir, self.out_prefix, self.log = job, Path(path), Path(out_dir), out_prefix, log
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.meshes = LiveMeshes(job.objects, job.leaves)
        self.saved = self.meshes.snapshot()
        self.shown, self.seen, self.previous, self.warned = [], None, None, None

    def poll(self, interval: float) -> Path | None:
        """Look once; the PNG rendered when a new version has stayed unchanged since the last look."""
        try:
            st = self.path.stat()
            signature = (st.st_mtime_ns, st.st_size)
        except FileNotFoundError:
            signature = None
        out = None
        if signature is not None and signature != self.seen and signature == self.previous:
            try:
                E = read_complete(self.path, self.job.leaves.n)
            except (InputFileError, OSError) as exc:
                if signature != self.warned:            # once a version, not every look
                    self.log(f"RadTR warning: {exc}; skipped, waiting for a complete file "
                             f"(looking again every {interval:g} s)")
                    self.warned = signature
            else:
                out = _show(self.job, self.meshes, E, self.out_dir / f"{self.out_prefix}{len(self.shown):04d}.png")
                self.shown.append(out)
                self.log(f"RadTR: {self.path.name} changed; rendered {out}")
                self.seen = signature
        self.previous = signature
        return out

    def close(self):
        self.meshes.restore(self.saved)


def watch(job, path, out_dir, polls: int, interval: float = 0.5, sleep=time.sleep, log=print,
          out_prefix: str = "watch_") -> list[Path]:
    """Poll ``path`` ``polls`` times, ``interval`` seconds apart (``Watcher``); returns the PNGs."""
    watcher = Watcher(job, path, out_dir, out_prefix, log)
    try:
        for _ in range(polls):
            watcher.poll(interval)
            sleep(interval)
    finally:
        watcher.close()
    return watcher.shown


def toggle_patch(job, origin, direction, emission: np.ndarray) -> tuple[int, np.ndarray]:
    """Click on a patch: (its id or -1, the new emission); the solve is shown in the result meshes."""
    from ..views import pick_patch, toggle_emission

    i = pick_patch(job.leaves, origin, direction)
    if i < 0:
        return i, emission
    E = toggle_emission(emission, i)
    LiveMeshes(job.objects, job.leaves).write(job.with_emission(E))
    return i, E
