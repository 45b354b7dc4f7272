"""Build the RadTR extension zip: fetch the pinned wheels, check the manifest, package.

    python tools/build_extension.py [--out dist]

Wheels come from PyPI (``tools/wheels.txt``) into ``wheels/``; the manifest's ``wheels``
list must name exactly those files. Packaging and manifest validation are Blender's own
(``blender_ext.py build`` from the installed ``bpy``).
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PLATFORM = "manylinux_2_28_x86_64"
#: Blender 4.2-5.0 run Python 3.11, Blender 5.1+ 3.13: a wheel of each; Blender installs its own.
PYTHONS = ("3.11", "3.13")


def fetch_wheels(dest: Path):
    reqs = [line.strip() for line in (ROOT / "tools" / "wheels.txt").read_text().splitlines()
            if line.strip() and not line.startswith("#")]
    dest.mkdir(exist_ok=True)
    for version in PYTHONS:
        subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--only-binary=:all:", "--no-deps",
                        "--platform", PLATFORM, "--python-version", version, "-d", str(dest), *reqs],
                       check=True)


def check_manifest(wheel_dir: Path):
    text = (ROOT / "blender_manifest.toml").read_text()
    listed = set(re.findall(r'"\./wheels/([^"]+\.whl)"', text))
    present = {p.name for p in wheel_dir.glob("*.whl")}
    if listed - present:
        raise SystemExit(f"manifest lists wheels not fetched: {sorted(listed - present)}")
    extra = present - listed
    for name in extra:
        (wheel_dir / name).unlink()


def blender_ext() -> Path:
    import importlib.util

    base = Path(importlib.util.find_spec("bpy").submodule_search_locations[0])
    found = sorted(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        raise SystemExit("blender_ext.py not found in the installed bpy module")
    return found[-1]


def build(out: Path) -> Path:
    fetch_wheels(ROOT / "wheels")
    check_manifest(ROOT / "wheels")
    out.mkdir(parents=True, exist_ok=True)
    subprocess.run([sys.executable, str(blender_ext()), "build", "--source-dir", str(ROOT),
                    "--output-dir", str(out)], check=True)
    zips = sorted(out.glob("radtr-*.zip"), key=lambda p: p.stat().st_mtime)
    return zips[-1]


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "dist"))
    print(build(Path(ap.parse_args().out)))
