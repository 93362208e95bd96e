"""Shared helpers for kernel modules: array conversion at the API boundary and ti.funcs.

Public kernel wrappers accept numpy arrays or Taichi ndarrays owned by the caller. Numpy inputs
are read in place on the CPU backend and copied into ndarrays once elsewhere (``kernel_array``),
results come back as numpy, written in place by the kernels on the CPU backend
(``output_array``: no device copy and no second host copy); ndarray inputs stay on the device and
results are returned as ndarrays, so an embedding pipeline never round-trips through the host.
"""

import numpy as np
from .taichi_compat import CPU_ARCHS, NDARRAY_TYPE, current_arch, ti

_NP_TO_TI = {
    np.dtype(np.float32): ti.f32,
    np.dtype(np.int32): ti.i32,
    np.dtype(np.uint32): ti.u32,
    np.dtype(np.uint8): ti.u8,
    np.dtype(np.int8): ti.i8,
    np.dtype(np.uint16): ti.u16,
    np.dtype(np.int64): ti.i64,
    np.dtype(np.float64): ti.f64,
}

_TI_TO_NP = {ti_type: np_type.type for np_type, ti_type in _NP_TO_TI.items()}

INT32_MAX = 2**31 - 1


def is_ndarray(a) -> bool:
    return isinstance(a, NDARRAY_TYPE)


def ndarray(dtype, shape):
    """Allocate a Taichi ndarray (dtype given as numpy dtype or Taichi type)."""
    if not isinstance(dtype, type(ti.f32)):
        dtype = _NP_TO_TI[np.dtype(dtype)]
    return ti.ndarray(dtype, shape)


def zeros(dtype, shape):
    """A Taichi ndarray of zeros. Filled from numpy rather than by ``Ndarray.fill``, whose kernel
    takes the value as i32: for 8-bit arrays its first compile prints a precision TaichiWarning
    on the CLI's stderr."""
    out = ndarray(dtype, shape)
    out.from_numpy(np.zeros(shape, _TI_TO_NP[out.dtype]))
    return out


def as_ndarray(a, dtype=None):
    """Return ``a`` as a Taichi ndarray: ndarrays pass through, numpy arrays are copied once."""
    if is_ndarray(a):
        return a
    arr = np.ascontiguousarray(a, dtype=dtype)
    if arr.size >= INT32_MAX:
        raise ValueError(f"array of {arr.size} elements exceeds Taichi's 32-bit indexing; tile the input")
    if arr.size == 0:
        # Taichi has no empty ndarray ('(0, 3) is not a valid shape' on a GPU arch): the wrappers
        # launch no kernel over no points, so the empty numpy array stands for it
        return arr
    out = ndarray(arr.dtype, arr.shape)
    out.from_numpy(arr)
    return out


def host_memory_backend() -> bool:
    """True when kernels run on the host CPU (x64, arm64), where numpy arrays are kernel
    arguments in place: Taichi passes their pointer, no copy."""
    return current_arch() in CPU_ARCHS


def cpu_block_dim(iterations: int):
    """``ti.loop_config(block_dim=ti.static(cpu_block_dim(n)))``: on the CPU, where block_dim is
    the iterations one thread takes at a time, ``n``; on GPUs, where it is threads per block
    (CUDA allows at most 1024, Vulkan refuses some sizes), Taichi's default. Evaluated when the
    kernel compiles, so one kernel serves every arch."""
    return iterations if host_memory_backend() else None


def kernel_array(a, dtype=None):
    """An input array as a kernel argument: ndarrays as they are; numpy arrays in place on the
    CPU backend (converted only when not contiguous or not of ``dtype``), else copied into an
    ndarray. For read-only inputs: a wrapper must not hand the result back as its own output."""
    if is_ndarray(a) or not host_memory_backend():
        return as_ndarray(a, dtype)
    arr = np.ascontiguousarray(a, dtype=dtype)
    if arr.size >= INT32_MAX:
        raise ValueError(f"array of {arr.size} elements exceeds Taichi's 32-bit indexing; tile the input")
    return arr


# m: float32 keeps about a centimetre up to this magnitude (a spacing of 2^-6 m from 2^17 m): larger
# coordinates given wider than float32 are world coordinates that the kernels' float32 would round
MAX_LOCAL_COORD = float(2**17)


def points_array(xyz, name: str = "xyz"):
    """Points (n, 3) as a kernel argument (float32, as kernel_array), checked first: the kernels
    read three columns unchecked (an (n, 2) array read memory past its end), and compute in float32
    (world coordinates of a projected CRS, hundreds of kilometres, lost decimetres: subtract a
    local origin first). Numpy input is also checked for NaN and infinity; ndarrays are the
    caller's device arrays and are taken as they are."""
    shape = tuple(int(v) for v in xyz.shape) if hasattr(xyz, "shape") else np.shape(xyz)
    if len(shape) != 2 or shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {shape}")
    if not is_ndarray(xyz):
        a = np.asarray(xyz)
        if a.dtype.kind not in "fiu":
            raise TypeError(f"{name} must hold numbers, got {a.dtype}")
        if a.size:
            low, high = a.min(), a.max()
            if not (np.isfinite(low) and np.isfinite(high)):
                raise ValueError(f"{name} holds non-finite coordinates (NaN or infinity)")
            largest = max(abs(float(low)), abs(float(high)))
            if a.dtype != np.float32 and largest > MAX_LOCAL_COORD:
                raise ValueError(f"{name} reaches {largest:.6g}: the kernels compute in float32, which keeps "
                                 f"{np.spacing(np.float32(largest)):.2g} m there; subtract a local origin first "
                                 f"(e.g. xyz - xyz.min(axis=0))")
        return kernel_array(a, np.float32)
    return kernel_array(xyz, np.float32)


def index_array(indices, points=None):
    """Neighbour indices (n, k) as a kernel argument (int32, as kernel_array). Numpy indices are
    checked first, since the kernels read the points they name unchecked (an index past the
    cloud read other memory or ended the process with a segmentation fault): -1 (no neighbour)
    or 0 .. points - 1, and one row per point (``points``: the count of the cloud they index,
    default their own rows)."""
    if not is_ndarray(indices):
        a = np.asarray(indices)
        if a.ndim != 2 or a.dtype.kind not in "iu":
            raise ValueError(f"neighbour indices must be integers of shape (n, k), got {a.dtype} {a.shape}")
        n = len(a) if points is None else int(points)
        if len(a) != n:
            raise ValueError(f"neighbour indices have {len(a)} rows for {n} points")
        low, high = (int(a.min()), int(a.max())) if a.size else (-1, -1)
        if low < -1 or high >= n:
            bad = low if low < -1 else high
            raise ValueError(f"neighbour index {bad} is outside the cloud of {n} points (-1 for none, else 0..{n - 1})")
    return kernel_array(indices, np.int32)


def output_array(dtype, shape, reference):
    """A zeroed result array for a wrapper whose input ``reference`` is numpy or an ndarray:
    numpy, which the kernels write in place, when ``reference`` is numpy and the kernels run in
    host memory (a 4 M-point k = 16 kNN call then runs about 1 s faster with 0.4 GB less peak
    memory, measured); else an ndarray. Pair with ``like_input`` on the way out."""
    if not is_ndarray(reference) and host_memory_backend():
        return np.zeros(shape, _TI_TO_NP.get(dtype, dtype))
    return ndarray(dtype, shape)


def to_numpy(a):
    return a.to_numpy() if is_ndarray(a) else np.asarray(a)


def like_input(result, reference):
    """Return ``result`` as numpy when ``reference`` was numpy, else as is (an ndarray)."""
    return result if is_ndarray(reference) else to_numpy(result)


def length(a) -> int:
    return int(a.shape[0]) if hasattr(a, "shape") else len(a)     # a list of points too


@ti.func
def f32_order_key(value: ti.f32) -> ti.i32:
    """Order-preserving map float32 -> int32, so min/max reductions can use integer atomics
    (deterministic, and portable to backends without float atomics)."""
    bits = ti.bit_cast(value, ti.i32)
    if bits < 0:
        bits = bits ^ 0x7FFFFFFF
    return bits


@ti.func
def f32_from_order_key(key: ti.i32) -> ti.f32:
    bits = key
    if bits < 0:
        bits = bits ^ 0x7FFFFFFF
    return ti.bit_cast(bits, ti.f32)
