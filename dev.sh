#!/usr/bin/env bash
# Set up .venv (Python 3.11, PyPI bpy and the rest) if needed, then run a job:
#   ./dev.sh solve   solve the bundled Cornell box, write out/cornell_box.png and .blend
#   ./dev.sh test    run the test suite (headless)
set -euo pipefail
cd "$(dirname "$0")"
PY=${PYTHON:-$(command -v python3.11 || command -v python3)}
if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c "import bpy, scipy, embreex, numba, pyopencl, pytest, matplotlib, distributed" 2>/dev/null; then
  "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -r requirements.txt
  # PoCL builds for the CPU its LLVM names; where it cannot, Intel's CPU runtime is the OpenCL
  # device (an ICD in the environment's own vendors folder, which the back-ends read).
  if ! .venv/bin/python -m radtr_addon backends opencl; then
    echo "dev.sh: PoCL cannot build here; installing Intel's CPU runtime for OpenCL" >&2
    .venv/bin/python -m pip install -q -r requirements-opencl-cpu.txt
    mkdir -p .venv/etc/OpenCL/vendors
    echo "$PWD/.venv/lib/libintelocl.so" > .venv/etc/OpenCL/vendors/intel-cpu.icd
  fi
fi
case "${1:-}" in
  solve)
    mkdir -p out
    .venv/bin/python -m radtr_addon solve cornell_box --out out/cornell_box.blend --render out/cornell_box.png
    ;;
  test)
    shift
    .venv/bin/python -m pytest "$@"
    ;;
  *)
    echo "usage: ./dev.sh solve | test [pytest args]" >&2
    exit 2
    ;;
esac
