"""The engine layer stays free of Blender: every module of ``radtr_addon`` (``blender/`` and
the GPU form-factor modules included: they import ``bpy`` and ``gpu`` only inside the
functions that draw) imports in a fresh interpreter where ``bpy``, ``gpu`` and ``mathutils``
cannot be imported, so an import of them at module level cannot creep back."""
import subprocess
import sys

from conftest import ROOT

BLOCKED = """
import importlib, sys
for name in ("bpy", "gpu", "mathutils", "bmesh"):
    sys.modules[name] = None                 # import of a None entry raises ImportError
failed = []
for module in sys.argv[1:]:
    try:
        importlib.import_module(module)
    except Exception as error:
        failed.append(f"{module}: {error!r}")
print("\\n".join(failed))
"""


def engine_modules() -> list[str]:
    out = []
    for path in sorted((ROOT / "radtr_addon").rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__main__":               # runs the command line when imported
            continue
        out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def test_every_engine_module_imports_without_blender():
    modules = engine_modules()
    assert "radtr_addon.hierarchical.contacts" in modules and "radtr_addon.blender.pipeline" in modules
    run = subprocess.run([sys.executable, "-c", BLOCKED, *modules], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == "", run.stdout
