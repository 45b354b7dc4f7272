"""The compiled loops' fallback: a kernel that cannot be built says why and gives None (the
numpy forms, tested equal to the compiled ones beside each use, take over), and the kernels
load from numba's cache whichever name the package is imported under."""
import subprocess
import sys
from pathlib import Path

import pytest

from radtr_addon import compiled

ROOT = str(Path(compiled.__file__).resolve().parents[2])


def test_a_kernel_that_cannot_be_built_gives_none_and_says_why():
    with pytest.warns(RuntimeWarning, match=r"compiled no_such_loop not built \(AttributeError: .*no_such_loop"):
        assert compiled.kernel("no_such_loop") is None


def test_kernels_build_under_either_package_name(tmp_path):
    """Imported as ``radtr_addon`` (the CLI) and as ``radtr.radtr_addon`` (the add-on through a
    symlink, as Blender and the Blender tests load it), one after the other in fresh
    processes sharing numba's cache: each builds every kernel with no warning (an entry
    cached under one module name once failed to load under the other)."""
    (tmp_path / "radtr").symlink_to(ROOT, target_is_directory=True)
    names = list(compiled._kernels().SMOKE)
    for package in ("radtr.radtr_addon", "radtr_addon", "radtr.radtr_addon"):
        code = (f"import sys; sys.path[:0] = [{ROOT!r}, {str(tmp_path)!r}]\n"
                f"from {package} import compiled\n"
                f"assert all(compiled.kernel(n) is not None for n in {names!r})")
        run = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-c", code],
                             capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, (package, run.stderr[-2000:])
