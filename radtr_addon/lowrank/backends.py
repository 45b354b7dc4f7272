"""Per-frame back-ends: B = E + rho * (U Z), the n x k by k x channels product, on some device.

A back-end is a class taking a ``LowRank`` (and a dtype) whose ``solve(E)`` returns B.
The small k-sized part (V^T E and the LU solves) stays on the CPU in every back-end; what
differs is where U lives and who multiplies it. ``register(name, cls)`` adds one (the seed's
MATLAB slot): ``BACKENDS`` is what the bench and the flashlight offer. A back-end class may
have a ``probe()`` returning why it cannot run on this machine (None when it can):
``unavailable(name)`` asks it once, and ``make_backend(..., fallback=True)`` then falls back
to numpy with that reason as a warning instead of failing.
"""
from __future__ import annotations

import os
import sys
import time
import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import RadTRError, SettingsError

BACKENDS: dict[str, type] = {}
#: The flashlight's back-end unless one is chosen (numpy stands in, with a warning, where it
#: cannot run).
DEFAULT_BACKEND = "numba"
_UNAVAILABLE: dict[str, str | None] = {}


class BackendUnavailable(RadTRError):
    """A back-end that cannot run on this machine (the message says why)."""


def register(name: str, cls: type):
    BACKENDS[name] = cls


def unavailable(name: str) -> str | None:
    """Why back-end ``name`` cannot run here, or None when it can (probed once per process)."""
    if name not in _UNAVAILABLE:
        probe = getattr(BACKENDS[name], "probe", None)
        _UNAVAILABLE[name] = probe() if probe else None
    return _UNAVAILABLE[name]


def make_backend(name: str, lowrank, dtype=np.float32, user: str = "", fallback: bool = False, warn=None):
    """Back-end ``name``; "user" calls your function ``user`` (``solvers.user``) every frame.

    An unavailable back-end raises ``BackendUnavailable`` with the reason, or with
    ``fallback`` gives the numpy one and passes the reason to ``warn(message)``.
    """
    if name == "user":
        return UserBackend(lowrank, dtype, user)
    if name not in BACKENDS:
        raise SettingsError(f"low-rank back-end must be one of {', '.join(BACKENDS)} or user, got '{name}'")
    reason = unavailable(name)
    if reason is not None:
        message = f"the {name} back-end is unavailable on this machine: {reason}"
        if not fallback:
            raise BackendUnavailable(message)
        if warn is not None:
            warn(f"{message}; using numpy instead")
        name = "numpy"
    return BACKENDS[name](lowrank, dtype)


class UserBackend:
    """Your function in the loop every frame: ``f(E=, U=, V=, rho=) -> B`` with U (n, k) dense,
    V (n, k) sparse and E, rho (n, channels); checked like a user solver (``solvers.user``)."""

    def __init__(self, lowrank, dtype, spec: str):
        from ..solvers.user import load_user_solver

        self.lowrank, self.spec = lowrank, spec
        self.function = load_user_solver(spec)
        self.seconds = {"coefficients": 0.0, "product": 0.0}

    def solve(self, E: np.ndarray) -> np.ndarray:
        from ..solvers.user import call_user_solver

        lr = self.lowrank
        t0 = time.perf_counter()
        B = call_user_solver(self.function, self.spec, lr.n, E=E, U=lr.U, V=lr.V, rho=lr.rho)
        self.seconds["product"] += time.perf_counter() - t0
        return B[:, :lr.channels]


#: Bytes of U one block of the colour product reads (``NumpyBackend``): small enough to stay
#: in cache while each channel's matrix-vector product reads it.
BLOCK_BYTES = 3 << 20


class NumpyBackend:
    """U in host memory, BLAS matrix-vector products per frame.

    Colour reads U in blocks of rows (``BLOCK_BYTES``), one GEMV per channel on each block
    while it is in cache: a GEMM with 3 columns copies (packs) U first and took 1.5x longer
    at 111,104 x 776 (33 against 21.5 ms; the read bound is 14 ms). The GEMVs are called
    transposed on U's row-major storage, which OpenBLAS reads once.
    """

    label, description = "NumPy", "BLAS matrix-vector products on the CPU"
    exact = True

    def __init__(self, lowrank, dtype=np.float32):
        from scipy.linalg import blas

        self.lowrank, self.dtype = lowrank, np.dtype(dtype)
        self.U = np.ascontiguousarray(lowrank.U, dtype=self.dtype)
        self.rho = lowrank.rho.astype(self.dtype)
        self._gemv = blas.sgemv if self.dtype == np.float32 else blas.dgemv
        self.rows = max(64, BLOCK_BYTES // max(1, self.U.shape[1] * self.dtype.itemsize))
        self.seconds = {"coefficients": 0.0, "product": 0.0}

    def solve(self, E: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        Z = self.lowrank.coefficients(E).astype(self.dtype)
        t1 = time.perf_counter()
        if Z.shape[1] == 1:                      # mono: one pass
            UZ = self._gemv(1.0, self.U.T, Z[:, 0], trans=1)[:, None]
        else:
            UZ = np.empty((self.lowrank.n, Z.shape[1]), dtype=self.dtype)
            for start in range(0, self.lowrank.n, self.rows):
                block = self.U[start:start + self.rows].T
                for c in range(Z.shape[1]):
                    UZ[start:start + self.rows, c] = self._gemv(1.0, block, Z[:, c], trans=1)
        B = E + self.rho * UZ
        self.seconds["coefficients"] += t1 - t0
        self.seconds["product"] += time.perf_counter() - t1
        return B


@lru_cache(maxsize=None)
def _numba_kernels(real: str = "float32"):
    """The compiled products B = E + rho (U Z) in ``real`` arithmetic (U widened to it):
    colour (3 sums a row, U read once) and mono.

    Rows in parallel (numba's threads), each row's k-long dot products vectorised along the
    row (fastmath lets the sums be reordered). numba compiles for the CPU its LLVM detects
    (a current LLVM; NUMBA_CPU_NAME=generic makes code for any x86-64).
    """
    from numba import njit, prange

    cast = np.dtype(real).type

    @njit(parallel=True, fastmath=True, cache=False)
    def colour(U, ZT, E, rho, B):
        z0, z1, z2 = ZT[0], ZT[1], ZT[2]
        for i in prange(U.shape[0]):
            s0 = s1 = s2 = cast(0)
            for g in range(U.shape[1]):
                u = cast(U[i, g])
                s0 += u * z0[g]
                s1 += u * z1[g]
                s2 += u * z2[g]
            B[i, 0] = E[i, 0] + rho[i, 0] * s0
            B[i, 1] = E[i, 1] + rho[i, 1] * s1
            B[i, 2] = E[i, 2] + rho[i, 2] * s2

    @njit(parallel=True, fastmath=True, cache=False)
    def mono(U, ZT, E, rho, B):
        z = ZT[0]
        for i in prange(U.shape[0]):
            s = cast(0)
            for g in range(U.shape[1]):
                s += cast(U[i, g]) * z[g]
            B[i, 0] = E[i, 0] + rho[i, 0] * s

    return colour, mono


def numba_error(dtypes=(np.float32, np.float64, np.int8)) -> str | None:
    """Why the numba products cannot be compiled here (for U of each of ``dtypes``), or None."""
    try:
        for dtype in dtypes:
            real = np.float32 if dtype == np.int8 else dtype
            colour, mono = _numba_kernels(np.dtype(real).name)
            U, Z = np.ones((4, 2), dtype), np.ones((3, 2), real)
            E = rho = np.ones((4, 3), real)
            B = np.empty((4, 3), real)
            colour(U, Z, E, rho, B)
            mono(U, Z[:1], E[:, :1], rho[:, :1], B[:, :1])
    except Exception as exc:            # not installed, or its LLVM cannot build for this CPU
        return _first_line(exc)
    return None


class NumbaBackend:
    """U in host memory, one compiled pass over it per frame for all channels (numba): at
    111,104 x 776 the colour product took 11 ms where the blocked GEMVs take 20-22 (the
    three channels' sums share each read of U)."""

    label, description = "Numba", "Compiled product on the CPU, every channel in one read of U"
    exact = True
    probe = staticmethod(numba_error)

    def __init__(self, lowrank, dtype=np.float32):
        self.lowrank, self.dtype = lowrank, np.dtype(dtype)
        self.U = self._host_U(lowrank)
        self.rho = np.ascontiguousarray(lowrank.rho, dtype=self.dtype)
        self._colour, self._mono = _numba_kernels(self.dtype.name)
        self.seconds = {"coefficients": 0.0, "product": 0.0}

    def _host_U(self, lowrank) -> np.ndarray:
        return np.ascontiguousarray(lowrank.U, dtype=self.dtype)

    def coefficients(self, E: np.ndarray) -> np.ndarray:
        return self.lowrank.coefficients(E)

    def solve(self, E: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        ZT = np.ascontiguousarray(self.coefficients(E).T, dtype=self.dtype)
        t1 = time.perf_counter()
        E = np.ascontiguousarray(E, dtype=self.dtype)
        B = np.empty_like(E)
        (self._mono if E.shape[1] == 1 else self._colour)(self.U, ZT, E, self.rho, B)
        self.seconds["coefficients"] += t1 - t0
        self.seconds["product"] += time.perf_counter() - t1
        return B


def quantize_columns(U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """U (n, k) as 8-bit integers by column, stored as U^T (k, n) int8, and the column scales
    (k,): U ~ q x scale, each entry off by at most scale / 2 (``int8_error_bound``)."""
    scale = np.abs(U).max(axis=0) / 127.0
    scale[scale == 0] = 1.0
    return np.ascontiguousarray(np.rint(U / scale).T.astype(np.int8)), scale


def int8_error_bound(scale: np.ndarray, Z: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Largest |B error| (n, channels) 8-bit U can add for coefficients Z (k, channels):
    rho x sum_g scale_g |Z_g| / 2."""
    return rho * (0.5 * scale @ np.abs(Z))


class Int8Columns:
    """U as 8-bit integers with a scale per column (``quantize_columns``), the scales folded
    into the coefficients: a mixin before a back-end class, whose U then takes a quarter of
    the bytes of float32; the error it adds is bounded by ``int8_error_bound``."""

    exact = False

    def _quantized(self, lowrank) -> np.ndarray:
        """U^T (k, n) as int8; sets ``scale``."""
        q, self.scale = quantize_columns(lowrank.U)
        return q

    def coefficients(self, E: np.ndarray) -> np.ndarray:
        return self.lowrank.coefficients(E) * self.scale[:, None]


class NumbaInt8Backend(Int8Columns, NumbaBackend):
    """``NumbaBackend`` reading U as 8-bit integers (``Int8Columns``)."""

    label, description = "Numba 8-bit", "Numba reading U as 8-bit integers: a quarter of the bytes, about 0.3% error"

    def _host_U(self, lowrank) -> np.ndarray:
        return np.ascontiguousarray(self._quantized(lowrank).T)


#: One work-item per patch; U is stored by columns (U^T row-major), so neighbouring
#: work-items read neighbouring words: coalesced on a GPU, vectorised across work-items by
#: PoCL on a CPU. Up to 3 channels are summed in one pass over U.
_KERNEL = """
__kernel void product(__global const REAL *UT, __global const REAL *Z, __global const REAL *E,
                      __global const REAL *rho, __global REAL *B, const int n, const int k, const int c) {
    int i = get_global_id(0);
    if (i >= n) return;
    REAL s0 = 0, s1 = 0, s2 = 0;
    for (int g = 0; g < k; ++g) {
        REAL u = UT[(size_t)g * n + i];
        s0 += u * Z[g * c];
        if (c > 1) { s1 += u * Z[g * c + 1]; s2 += u * Z[g * c + 2]; }
    }
    B[i * c] = E[i * c] + rho[i * c] * s0;
    if (c > 1) {
        B[i * c + 1] = E[i * c + 1] + rho[i * c + 1] * s1;
        B[i * c + 2] = E[i * c + 2] + rho[i * c + 2] * s2;
    }
}
"""


#: Where the OpenCL loader also looks for drivers: this Python environment's own vendors
#: folder. ``dev.sh`` installs Intel's CPU runtime there on a CPU that PoCL's LLVM cannot name.
ENVIRONMENT_ICDS = Path(sys.prefix) / "etc" / "OpenCL" / "vendors"


def opencl_devices() -> list:
    """Every OpenCL device the loader offers, GPUs first (none when no driver loads).

    Drivers in ``ENVIRONMENT_ICDS`` are offered beside pyopencl's PoCL (the loader reads
    that folder instead of /etc/OpenCL/vendors when it exists and OCL_ICD_VENDORS is unset).
    """
    import pyopencl as cl

    if ENVIRONMENT_ICDS.is_dir() and "OCL_ICD_VENDORS" not in os.environ:
        os.environ["OCL_ICD_VENDORS"] = str(ENVIRONMENT_ICDS)
    try:
        devices = [d for p in cl.get_platforms() for d in p.get_devices()]
    except cl.Error:
        return []
    return sorted(devices, key=lambda d: not d.type & cl.device_type.GPU)


def opencl_device(source: str = _KERNEL):
    """The first device (``opencl_devices``) that builds ``source`` for float and double,
    and None; or None and why no device can (each device's first error). PYOPENCL_CTX,
    when set, chooses the device instead.

    PoCL compiles for the CPU that its LLVM detects; on a CPU that LLVM cannot name its
    build fails ("unknown target CPU 'generic'") and the next device is tried.
    """
    try:
        import pyopencl as cl
    except ImportError as exc:
        return None, _first_line(exc)
    if os.environ.get("PYOPENCL_CTX"):
        try:
            candidates = cl.create_some_context(interactive=False).devices
        except Exception as exc:            # any failure of the driver stack means "cannot run here"
            return None, _first_line(exc)
    else:
        candidates = opencl_devices()
    errors = []
    for device in candidates:
        try:
            ctx = cl.Context([device])
            for real in ("float", "double"):
                _build(ctx, source.replace("REAL", real))
            return device, None
        except Exception as exc:
            errors.append(f"{device.platform.name} {device.name.strip()}: {_first_line(exc)}")
    return None, "; ".join(errors) or "no OpenCL driver is installed"


def _build(ctx, source: str):
    """The program of ``source`` built for ``ctx``; a build log alone is no warning (Intel's
    runtime logs every build), a failed build still raises with it."""
    import pyopencl as cl

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cl.CompilerWarning)
        return cl.Program(ctx, source).build()


def _first_line(exc: Exception) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"


def opencl_build_error(source: str = _KERNEL) -> str | None:
    """Why no OpenCL device here can build ``source`` (float and double), or None."""
    return opencl_device(source)[1]


class OpenCLBackend:
    """U in an OpenCL device's memory (PoCL on the CPU here, a GPU where present); one kernel
    per frame, one work-item per patch."""

    label, description = "OpenCL", "PyOpenCL: a GPU where present, PoCL (or Intel's runtime) on the CPU otherwise"
    exact = True                        # equals numpy float64 to float32 rounding
    source = _KERNEL

    probe = staticmethod(opencl_build_error)

    def __init__(self, lowrank, dtype=np.float32):
        import pyopencl as cl

        self.cl, self.lowrank, self.dtype = cl, lowrank, np.dtype(dtype)
        device, reason = opencl_device(self.source)
        if device is None:
            raise BackendUnavailable(f"no OpenCL device can build the kernel: {reason}")
        self.ctx = cl.Context([device])
        self.queue = cl.CommandQueue(self.ctx)
        real = "float" if self.dtype == np.float32 else "double"
        self.kernel = cl.Kernel(_build(self.ctx, self.source.replace("REAL", real)), "product")
        mf = cl.mem_flags
        self.U = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=self._device_U(lowrank))
        self.rho = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                             hostbuf=np.ascontiguousarray(lowrank.rho, dtype=self.dtype))
        self.out = np.empty(lowrank.rho.shape, dtype=self.dtype)
        self.B = cl.Buffer(self.ctx, mf.WRITE_ONLY, self.out.nbytes)
        self.seconds = {"coefficients": 0.0, "product": 0.0}
        self.device = self.ctx.devices[0].name

    def _device_U(self, lowrank) -> np.ndarray:
        """U as the kernel reads it: by columns (U^T, row-major)."""
        return np.ascontiguousarray(lowrank.U.T, dtype=self.dtype)

    def coefficients(self, E: np.ndarray) -> np.ndarray:
        """Z (k, channels) the kernel multiplies U by."""
        return self.lowrank.coefficients(E)

    def solve(self, E: np.ndarray) -> np.ndarray:
        cl = self.cl
        t0 = time.perf_counter()
        Z = np.ascontiguousarray(self.coefficients(E), dtype=self.dtype)
        t1 = time.perf_counter()
        mf = cl.mem_flags
        z = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=Z)
        e = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(E, dtype=self.dtype))
        self.kernel(self.queue, (self.lowrank.n,), None, self.U, z, e, self.rho, self.B,
                    np.int32(self.lowrank.n), np.int32(self.lowrank.k), np.int32(self.lowrank.channels))
        cl.enqueue_copy(self.queue, self.out, self.B)
        self.seconds["coefficients"] += t1 - t0
        self.seconds["product"] += time.perf_counter() - t1
        return self.out.copy()


class OpenCLInt8Backend(Int8Columns, OpenCLBackend):
    """``OpenCLBackend`` reading U as 8-bit integers (``Int8Columns``): the product is bound
    by reading U, and the kernel only widens each byte (the bench reports the error against
    float64)."""

    label, description = "OpenCL 8-bit", "OpenCL reading U as 8-bit integers: a quarter of the bytes, about 0.3% error"
    source = _KERNEL.replace("const REAL *UT", "const char *UT")
    probe = staticmethod(lambda: opencl_build_error(OpenCLInt8Backend.source))

    def _device_U(self, lowrank) -> np.ndarray:
        return self._quantized(lowrank)


register("numpy", NumpyBackend)
register("numba", NumbaBackend)
register("numba-int8", NumbaInt8Backend)
register("opencl", OpenCLBackend)
register("opencl-int8", OpenCLInt8Backend)
