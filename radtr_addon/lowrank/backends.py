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

import time

import numpy as np

from ..errors import RadTRError, SettingsError

BACKENDS: dict[str, type] = {}
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


def opencl_build_error(source: str = _KERNEL) -> str | None:
    """Why ``source`` cannot be built for an OpenCL device here (float and double), or None.

    PoCL compiles for the CPU that its LLVM detects; on a CPU that LLVM cannot name the
    build fails ("unknown target CPU 'generic'"), and that message is the reason returned.
    """
    try:
        import pyopencl as cl

        ctx = cl.create_some_context(interactive=False)
        for real in ("float", "double"):
            cl.Program(ctx, source.replace("REAL", real)).build()
    except Exception as exc:            # any failure of the driver stack means "cannot run here"
        first = " ".join(str(exc).split())[:300]
        return f"{type(exc).__name__}: {first}"
    return None


class OpenCLBackend:
    """U in an OpenCL device's memory (PoCL on the CPU here, a GPU where present); one kernel
    per frame, one work-item per patch."""

    exact = True                        # equals numpy float64 to float32 rounding
    source = _KERNEL

    probe = staticmethod(opencl_build_error)

    def __init__(self, lowrank, dtype=np.float32):
        import pyopencl as cl

        self.cl, self.lowrank, self.dtype = cl, lowrank, np.dtype(dtype)
        self.ctx = cl.create_some_context(interactive=False)
        self.queue = cl.CommandQueue(self.ctx)
        real = "float" if self.dtype == np.float32 else "double"
        self.kernel = cl.Kernel(cl.Program(self.ctx, self.source.replace("REAL", real)).build(), "product")
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


class OpenCLInt8Backend(OpenCLBackend):
    """``OpenCLBackend`` reading U as 8-bit integers with a scale per column (a quarter of the
    bytes of float32: the product is bound by reading U). The scales are folded into the
    coefficients, so the kernel only widens each byte; the error it adds is bounded by
    ``int8_error_bound`` (the bench reports it against float64)."""

    exact = False
    source = _KERNEL.replace("const REAL *UT", "const char *UT")
    probe = staticmethod(lambda: opencl_build_error(OpenCLInt8Backend.source))

    def _device_U(self, lowrank) -> np.ndarray:
        q, self.scale = quantize_columns(lowrank.U)
        return q

    def coefficients(self, E: np.ndarray) -> np.ndarray:
        return self.lowrank.coefficients(E) * self.scale[:, None]


register("numpy", NumpyBackend)
register("opencl", OpenCLBackend)
register("opencl-int8", OpenCLInt8Backend)
