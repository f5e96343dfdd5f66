"""OpenCL backend: pyopencl kernels for PoCL on CPUs and any OpenCL device elsewhere.

The kernels are the gather forms of the numpy reference (:mod:`cansim.backends.numpy_backend`):

* ``conv_*`` - one separable periodic 1-D pass (Alg 3/4). The reference scatters
  ``out[i + j - c] += a[i] * taps[j]`` with wrap-around; here every output cell gathers
  ``out[m] = sum_j taps[j] * a[m + c - j]`` (the reversed kernel), so no atomics are
  needed, taps longer than the axis wrap and add up exactly as ``np.roll`` sums do, and
  the taps are visited in the reference's order.
* ``inhibit`` - the last inhibition pass fused with ``b = e - e (*) I`` (Alg 4,
  OpenRatSLAM semantics), global inhibition ``max(b - phi, 0)`` (Alg 5) and one partial
  sum per work-group; ``sum_partials`` reduces those to the total for normalisation.
* ``shift_*`` - the fractional shift of SPEC §1.4 along one axis, the reference's
  expression ``(1 - f) a[m - lo] + f a[m - lo - 1]``; axes are applied one after another
  (the product of the 1-D splits). The split of a cell is looked up by its *condition
  index* (the flat index over the axes that are not shifted), so one kernel serves the
  uniform shift (one condition) and the heading-conditional translation (one shift
  vector per orientation slice). The first pass after the dynamics also normalises.
* ``scatter_set`` - writes a few precomputed cells (local-view injection).

Numerics: cells are stored in the grid's dtype; every intermediate (the excited and
inhibited activity, sums, split weights) is held in ``double`` when the device supports
``cl_khr_fp64`` (PoCL and Intel CPU runtimes do), as the numpy reference does, and in
``float`` otherwise (float32 grids only; results then agree with numpy to ~1e-6
relative). Floating-point contraction is disabled, the taps and shift axes are visited
in the reference's order and results are rounded to the grid dtype where the reference
stores them (after normalisation and after each shift stage), so with fp64 the results
equal numpy's up to the order of the one global sum (float32 grids: bit-identical in
practice, which also keeps argmax ties and hence decoding identical).

Decoding (argmax + population vector, Eq 5.11-5.12) and standalone injection run on the
host: the backend contract hands activity back as a host array after every call, so the
whole grid is on the host anyway and :func:`cansim.decoding.population_vector_window`
there is exact (first-argmax tie-breaking in C order) and cheaper than a device
reduction plus a second read-back.

Device choice: ``OpenCLBackend(device=...)`` or the environment variable
``CANSIM_OPENCL_DEVICE``, either ``"P:D"`` (platform and device index, as pyopencl's
``PYOPENCL_CTX``) or a case-insensitive substring of ``"<platform name> <device name>"``.
By default a GPU is preferred, then the other devices in platform order; a device whose
OpenCL compiler fails on the kernels is passed over. PoCL 3.0 of
``pocl-binary-distribution`` bundles LLVM 14, which cannot compile for CPUs it does not
know (e.g. AMD Zen 5: "unknown target CPU 'generic'"); such a device is recognised from
its version string and skipped. On those machines Intel's CPU runtime works: ``pip
install intel-opencl-rt`` and point the ICD loader at it with ``OCL_ICD_VENDORS=<dir>``
where ``<dir>`` holds an ``.icd`` file containing the path of ``<prefix>/lib/libintelocl.so``.

Nothing happens at import. The device is looked up when the backend is constructed; the
context, queue and program are created on first use (or by :meth:`OpenCLBackend.prepare`)
and the built program is cached per storage dtype. pyopencl and PoCL also keep on-disk
binary caches (``PYOPENCL_CACHE_DIR`` / ``POCL_CACHE_DIR``), so only a process's first
build after a change of kernel source pays the full compile.
"""

from __future__ import annotations

import logging
import os
import time
import warnings
from dataclasses import dataclass, field
from typing import Optional, Sequence, Union

import numpy as np
import pyopencl as cl

from cansim.backends.base import Backend
from cansim.decoding import population_vector_window
from cansim.errors import BackendUnavailableError, InvalidInputError

__all__ = ["OpenCLBackend", "DEVICE_ENV_VAR", "list_devices"]

log = logging.getLogger(__name__)

#: environment variable naming the OpenCL device ("P:D" or a name substring)
DEVICE_ENV_VAR = "CANSIM_OPENCL_DEVICE"

_INSTALL_HINT = 'pip install "cansim[opencl]" (pyopencl + pocl-binary-distribution, a CPU OpenCL platform)'

_SOURCE = r"""
#ifdef NEED_FP64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif
#pragma OPENCL FP_CONTRACT OFF

/* Gather form of the periodic scatter convolution out[i + j - c] += in[i] * taps[j]
   along one axis (length n, element stride `stride`): out[m] = sum_j taps[j] in[m + c - j]. */
#define CONV_GATHER(IN, coord, base, n, stride)                           \
    int src = (coord + c) % n;                                            \
    ACC s = 0;                                                            \
    for (int j = 0; j < w; ++j) {                                         \
        s += taps[toff + j] * (ACC)IN[base + src * stride];               \
        src = (src == 0) ? n - 1 : src - 1;                               \
    }

/* Per-axis NDRange over the cells after the axis (inner, stride st), on it (coord, n)
   and before it (outer): (inner, n, outer) with base = g0 + g2 * n * inner, so that
   neighbouring work-items read neighbouring memory; for the last axis (st == 1)
   (n, outer, 1) with base = g0 * n, work-items along the axis. No integer divisions. */
#define AXIS_INDEX                                                        \
    const int g0 = get_global_id(st == 1), coord = get_global_id(st != 1); \
    const int g2 = get_global_id(2), n = get_global_size(st != 1);        \
    const int base = g0 * s0 + g2 * s2;

#define CONV_KERNEL(NAME, IN_T)                                           \
__kernel void NAME(__global const IN_T *in, __global ACC *out,            \
                   const int s0, const int s2, const int st,              \
                   __global const ACC *taps, const int toff, const int w, \
                   const int c)                                           \
{                                                                         \
    AXIS_INDEX                                                            \
    CONV_GATHER(in, coord, base, n, st)                                   \
    out[base + coord * st] = s;                                           \
}

CONV_KERNEL(conv_store, T)
CONV_KERNEL(conv_acc, ACC)

/* Last inhibition pass + b = e - e(*)I + global inhibition + per-group partial sums. */
__kernel void inhibit(__global const ACC *in, __global const ACC *e, __global ACC *out,
                      __global const ACC *taps, const int toff, const int w,
                      const int c, const int n, const int stride, const int total, const ACC phi,
                      __global ACC *partial, __local ACC *scratch)
{
    const int gid = get_global_id(0);
    const int lid = get_local_id(0);
    ACC v = 0;
    if (gid < total) {
        const int coord = (gid / stride) % n;
        const int base = gid - coord * stride;
        CONV_GATHER(in, coord, base, n, stride)
        const ACC b = e[gid] - s;
        v = (b >= phi) ? b - phi : (ACC)0;
        out[gid] = v;
    }
    scratch[lid] = v;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int o = get_local_size(0) / 2; o > 0; o >>= 1) {
        if (lid < o) scratch[lid] += scratch[lid + o];
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lid == 0) partial[get_group_id(0)] = scratch[0];
}

/* One work-group adds the partial sums in a fixed order: total[0]. */
__kernel void sum_partials(__global const ACC *partial, const int m, __global ACC *total,
                           __local ACC *scratch)
{
    const int lid = get_local_id(0);
    const int L = get_local_size(0);
    ACC s = 0;
    for (int i = lid; i < m; i += L) s += partial[i];
    scratch[lid] = s;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int o = L / 2; o > 0; o >>= 1) {
        if (lid < o) scratch[lid] += scratch[lid + o];
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lid == 0) total[0] = scratch[0];
}

/* Fractional shift along one axis (SPEC 1.4): out[m] = (1 - f) in[m - lo] + f in[m - lo - 1]
   (wrapped), the same expression as the reference's _fractional_roll. NDRange as the
   convolution; n = 1 copies. The split of a cell is
   table[toff + 2 cond + {0, 1}] = (integer part mod n, fraction) for its condition
   index cond: 0 (cmode 0, uniform shift), i % ncond (cmode 1, the condition axes are the
   trailing ones) or sum_ax coord[ax] * cstride[ax] (cmode 2, any layout; meta = [ndim,
   shape, stride, cstride]). With use_norm every value read is first normalised by
   norm[0] and rounded to the storage type, as the reference stores the normalised
   activity. */
#define READ(IN, k) (use_norm ? (ACC)(T)((ACC)IN[k] / norm[0]) : (ACC)IN[k])
#define SHIFT_KERNEL(NAME, IN_T, OUT_T)                                   \
__kernel void NAME(__global const IN_T *in, __global OUT_T *out,          \
                   const int s0, const int s2, const int st,              \
                   const int cmode, const int ncond,                      \
                   __global const int *meta,                              \
                   __global const ACC *table, const int toff,             \
                   __global const ACC *norm, const int use_norm)          \
{                                                                         \
    AXIS_INDEX                                                            \
    const int gid = base + coord * st;                                    \
    const int i = (st == 1) ? 0 : g0;  /* index among the inner cells */  \
    int cond = 0;                                                         \
    if (cmode == 1) {                                                     \
        cond = i % ncond;                                                 \
    } else if (cmode == 2) {                                              \
        const int nd = meta[0];                                           \
        for (int ax = 0; ax < nd; ++ax)                                   \
            if (meta[1 + 2 * nd + ax] != 0)                               \
                cond += ((gid / meta[1 + nd + ax]) % meta[1 + ax])        \
                        * meta[1 + 2 * nd + ax];                          \
    }                                                                     \
    const int lo = (int)table[toff + 2 * cond];                           \
    const ACC f = table[toff + 2 * cond + 1];                             \
    int src = coord - lo;                                                 \
    if (src < 0) src += n;                                                \
    ACC acc = READ(in, base + src * st);                                  \
    if (f != 0) {                                                         \
        src = (src == 0) ? n - 1 : src - 1;                               \
        acc = ((ACC)1 - f) * acc + f * READ(in, base + src * st);         \
    }                                                                     \
    out[gid] = (OUT_T)acc;                                                \
}

SHIFT_KERNEL(shift_store_store, T, T)
SHIFT_KERNEL(shift_store_acc, T, ACC)
SHIFT_KERNEL(shift_acc_store, ACC, T)
SHIFT_KERNEL(shift_acc_acc, ACC, ACC)

/* a[idx[i]] = val[i] for distinct indices (injection, values computed on the host). */
__kernel void scatter_set(__global T *a, __global const int *idx, __global const T *val,
                          const int m)
{
    const int i = get_global_id(0);
    if (i < m) a[idx[i]] = val[i];
}
"""


# ----------------------------------------------------------------------------- devices
def _platforms() -> list:
    try:
        platforms = cl.get_platforms()
    except cl.Error as exc:  # e.g. PLATFORM_NOT_FOUND_KHR from the ICD loader
        raise BackendUnavailableError(
            f"the opencl backend found no OpenCL platform ({exc}); run: {_INSTALL_HINT}"
        ) from exc
    if not platforms:
        raise BackendUnavailableError(f"the opencl backend found no OpenCL platform; run: {_INSTALL_HINT}")
    return list(platforms)


def _devices_of(platform) -> list:
    try:
        return list(platform.get_devices())
    except cl.Error:  # DEVICE_NOT_FOUND on a platform without devices
        return []


def list_devices() -> list[tuple[str, "cl.Device"]]:
    """Every OpenCL device as ``("P:D <platform name> / <device name>", device)``.

    Raises
    ------
    BackendUnavailableError
        No OpenCL platform is installed.
    """
    out = []
    for p_i, p in enumerate(_platforms()):
        for d_i, d in enumerate(_devices_of(p)):
            out.append((f"{p_i}:{d_i} {p.name.strip()} / {d.name.strip()}", d))
    return out


def _select_devices(spec: Union[str, "cl.Device", None]) -> tuple[list, bool]:
    """Candidate devices in order of preference and whether the user chose explicitly."""
    if isinstance(spec, cl.Device):
        return [spec], True
    if spec is None:
        spec = os.environ.get(DEVICE_ENV_VAR) or None
    devices = list_devices()
    if not devices:
        raise BackendUnavailableError(
            f"the opencl backend found OpenCL platforms but no device; run: {_INSTALL_HINT}"
        )
    if spec is None:
        usable = [(label, d) for label, d in devices if _unusable_reason(d) is None]
        if not usable:
            reasons = "; ".join(f"{label}: {_unusable_reason(d)}" for label, d in devices)
            raise BackendUnavailableError(f"no usable OpenCL device ({reasons})")
        gpus = [d for _, d in usable if d.type & cl.device_type.GPU]
        return gpus + [d for _, d in usable if not d.type & cl.device_type.GPU], False
    spec = str(spec).strip()
    if ":" in spec and all(part.strip().isdigit() for part in spec.split(":", 1)):
        key = ":".join(part.strip() for part in spec.split(":", 1))
        chosen = [d for label, d in devices if label.split(" ", 1)[0] == key]
    else:
        chosen = [d for label, d in devices if spec.lower() in label.split(" ", 1)[1].lower()]
    if not chosen:
        listing = "; ".join(label for label, _ in devices)
        raise BackendUnavailableError(
            f"no OpenCL device matches {spec!r} (from the device argument or ${DEVICE_ENV_VAR}); "
            f"available: {listing}. Give 'P:D' indices or part of a name."
        )
    reason = _unusable_reason(chosen[0])
    if reason is not None:
        raise BackendUnavailableError(f"OpenCL device {chosen[0].name.strip()!r} is not usable: {reason}")
    return chosen[:1], True


def _unusable_reason(device) -> Optional[str]:
    """Why a device is known not to build OpenCL C here, or None.

    PoCL reports the LLVM CPU name it compiles for at the end of its device version
    (``HSTR: pthread-x86_64-...-<cpu>``); on x86 ``generic`` means its LLVM did not
    recognise the CPU, and its clang then rejects every program ("unknown target CPU
    'generic'"), e.g. PoCL 3.0 (LLVM 14) of pocl-binary-distribution on AMD Zen 5.
    """
    version = str(getattr(device, "version", ""))
    if "PoCL HSTR" in version and "x86_64" in version and version.rstrip().endswith("-generic"):
        return (
            "this PoCL's LLVM does not recognise the CPU and cannot compile for it; install an "
            "OpenCL runtime that knows it (a newer PoCL, or Intel's CPU runtime: pip install "
            "intel-opencl-rt, then list <prefix>/lib/libintelocl.so in an .icd file in the "
            "directory named by $OCL_ICD_VENDORS)"
        )
    return None


def _has_fp64(device) -> bool:
    return bool(device.double_fp_config) or "cl_khr_fp64" in device.extensions


# ------------------------------------------------------------------------------- state
@dataclass
class _Program:
    """The built program for one storage dtype and its kernels."""

    storage: np.dtype
    acc: np.dtype
    kernels: dict


@dataclass
class _Buffers:
    """Device buffers for one grid shape and dtype."""

    shape: tuple[int, ...]
    size: int
    act: "cl.Buffer"  # activity in storage dtype (input, injection target)
    res: "cl.Buffer"  # result in storage dtype
    tmp: list  # three accumulator-dtype grids
    partial: "cl.Buffer"
    total: "cl.Buffer"
    n_groups: int
    meta: dict = field(default_factory=dict)  # (axes, cstrides) -> cl.Buffer
    small: dict = field(default_factory=dict)  # name -> (cl.Buffer, nbytes)


class OpenCLBackend(Backend):
    """CAN kernels in OpenCL (pyopencl), for PoCL on CPUs and any OpenCL GPU.

    Parameters
    ----------
    device : str, pyopencl.Device or None
        ``"P:D"`` platform and device index, or part of ``"<platform> <device>"`` name;
        None reads ``$CANSIM_OPENCL_DEVICE``, else prefers a GPU, then any device whose
        compiler builds the kernels.
    fp64 : bool or None
        Double-precision intermediates: None uses them when the device supports
        ``cl_khr_fp64``; False forces single precision (float32 grids only, as on a
        device without fp64); True requires fp64.
    work_group : int
        Work-group size of the reductions (a power of two, capped by the device).

    Raises
    ------
    BackendUnavailableError
        No OpenCL platform or usable device, no device matching ``device``, or
        ``fp64=True`` on a device without it. The message says what to install or choose.
    InvalidInputError
        ``work_group`` is not a power of two.

    Notes
    -----
    Every call uploads the activity, runs its kernels and downloads the result (the
    contract works on host arrays); :meth:`step` does the whole iteration with one
    upload, one small table upload, ``2 * ndim + 1`` kernel launches for the dynamics,
    one per shifted axis and one download. Launch and transfer overhead (tens of microseconds each on CPU runtimes)
    therefore dominates small grids (a 360-cell ring, 21 x 21 x 36); the dense kernels
    pay off on large grids (10^6 cells), where they run on every core (and on GPUs).
    """

    name = "opencl"

    def __init__(
        self,
        device: Union[str, "cl.Device", None] = None,
        *,
        fp64: Optional[bool] = None,
        work_group: int = 64,
    ) -> None:
        if not isinstance(work_group, (int, np.integer)) or work_group < 1 or work_group & (work_group - 1):
            raise InvalidInputError(f"work_group must be a power of two >= 1 (e.g. 64), got {work_group!r}")
        self._candidates, self._explicit = _select_devices(device)
        self._fp64_request = fp64
        if fp64 and self._explicit and not _has_fp64(self._candidates[0]):
            raise BackendUnavailableError(
                f"OpenCL device {self._candidates[0].name.strip()!r} has no float64 support (cl_khr_fp64); "
                "use fp64=None/False or another device"
            )
        self._wg_request = int(work_group)
        self._device = None
        self._ctx = None
        self._queue = None
        self._programs: dict[np.dtype, _Program] = {}
        self._buffers: dict[tuple, _Buffers] = {}
        self._taps_key: Optional[bytes] = None
        self._taps_buf = None
        self._taps_layout: list[tuple[int, int]] = []
        #: seconds spent building each program, by storage dtype name
        self.build_seconds: dict[str, float] = {}

    # --------------------------------------------------------------------- set-up
    @property
    def device(self):
        """The pyopencl Device in use (creates the context on first access)."""
        self._ensure_context()
        return self._device

    def _ensure_context(self) -> None:
        if self._ctx is None:
            self._open(self._candidates[0])

    def _open(self, device) -> None:
        self._device = device
        self._ctx = cl.Context([device])
        self._queue = cl.CommandQueue(self._ctx, device)
        self._programs.clear()
        self._buffers.clear()
        self._taps_key = None
        self._wg = max(1, min(self._wg_request, _pow2_floor(device.max_work_group_size)))

    def prepare(self, dtype: np.dtype | type = np.float32) -> None:
        """Create the context and build the program for ``dtype`` now (otherwise done on first use).

        Raises
        ------
        BackendUnavailableError
            The device cannot compile the kernels, or ``dtype`` is float64 on a device
            without fp64.
        """
        self._program(np.dtype(dtype))

    def _program(self, storage: np.dtype) -> _Program:
        if self._ctx is not None and storage in self._programs:
            return self._programs[storage]
        if storage not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise BackendUnavailableError(f"the opencl backend stores float32 or float64 grids, not {storage}")
        errors = []
        candidates = [self._device] if self._ctx is not None else self._candidates
        for i, dev in enumerate(candidates):
            if self._ctx is None or dev is not self._device:
                self._open(dev)
            try:
                prog = self._build(storage)
            except BackendUnavailableError as exc:
                if self._explicit or storage == np.dtype(np.float64) and not _has_fp64(dev):
                    raise
                errors.append(str(exc))
                if i + 1 < len(candidates):
                    log.warning("%s; trying the next OpenCL device", exc)
                    continue
                raise BackendUnavailableError(
                    "no OpenCL device could build the cansim kernels: " + " | ".join(errors)
                ) from exc
            self._programs[storage] = prog
            self._candidates = [dev]
            return prog
        raise AssertionError("unreachable")  # pragma: no cover

    def _build(self, storage: np.dtype) -> _Program:
        dev = self._device
        fp64 = _has_fp64(dev)
        if self._fp64_request and not fp64:
            raise BackendUnavailableError(
                f"OpenCL device {dev.name.strip()!r} has no float64 support (cl_khr_fp64); "
                "use fp64=None/False or another device"
            )
        use64 = fp64 and self._fp64_request is not False
        if storage == np.dtype(np.float64) and not use64:
            why = "has no float64 support (cl_khr_fp64)" if not fp64 else "was opened with fp64=False"
            raise BackendUnavailableError(
                f"OpenCL device {dev.name.strip()!r} {why}: use dtype=float32 for this population, "
                "or the numpy/numba backend for float64"
            )
        acc = np.dtype(np.float64) if use64 else np.dtype(np.float32)
        ctype = {np.dtype(np.float32): "float", np.dtype(np.float64): "double"}
        options = [f"-DT={ctype[storage]}", f"-DACC={ctype[acc]}"]
        if use64:
            options.append("-DNEED_FP64")
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():  # compiler chatter (e.g. vectoriser notes) is not an error
                warnings.simplefilter("ignore", cl.CompilerWarning)
                program = cl.Program(self._ctx, _SOURCE).build(options=options)
        except cl.Error as exc:
            text = str(exc)
            lines = [ln.strip() for ln in text.splitlines() if "error" in ln.lower()]
            hint = ""
            if "unknown target CPU" in text:
                hint = (
                    " (this PoCL's LLVM does not know this CPU; install another OpenCL runtime, "
                    f"e.g. a newer PoCL or Intel's CPU runtime, or pick a device with ${DEVICE_ENV_VAR})"
                )
            raise BackendUnavailableError(
                f"OpenCL device {dev.name.strip()!r} failed to build the cansim kernels{hint}: "
                + (lines[-1] if lines else text.strip().splitlines()[-1])[:300]
            ) from exc
        self.build_seconds[storage.name] = time.perf_counter() - t0
        log.info("built cansim OpenCL program (%s) on %s in %.2f s", storage.name, dev.name.strip(),
                 self.build_seconds[storage.name])
        kernels = {k.function_name: k for k in program.all_kernels()}
        i32 = np.int32
        sig_conv = [None, None, i32, i32, i32, None, i32, i32, i32]
        kernels["conv_store"].set_scalar_arg_dtypes(sig_conv)
        kernels["conv_acc"].set_scalar_arg_dtypes(sig_conv)
        kernels["inhibit"].set_scalar_arg_dtypes(
            [None, None, None, None, i32, i32, i32, i32, i32, i32, acc, None, None]
        )
        kernels["sum_partials"].set_scalar_arg_dtypes([None, i32, None, None])
        for name in ("shift_store_store", "shift_store_acc", "shift_acc_store", "shift_acc_acc"):
            kernels[name].set_scalar_arg_dtypes([None, None, i32, i32, i32, i32, i32, None, None, i32, None, i32])
        kernels["scatter_set"].set_scalar_arg_dtypes([None, None, None, i32])
        return _Program(storage, acc, kernels)

    def _bufs(self, shape: tuple[int, ...], prog: _Program) -> _Buffers:
        key = (shape, prog.storage)
        b = self._buffers.get(key)
        if b is None:
            size = int(np.prod(shape))
            if size >= 2**31:
                raise BackendUnavailableError("the opencl backend indexes cells with 32-bit ints; grid too large")
            mf = cl.mem_flags
            s_bytes = size * prog.storage.itemsize
            a_bytes = size * prog.acc.itemsize
            n_groups = -(-size // self._wg)
            b = _Buffers(
                shape=shape,
                size=size,
                act=cl.Buffer(self._ctx, mf.READ_WRITE, s_bytes),
                res=cl.Buffer(self._ctx, mf.READ_WRITE, s_bytes),
                tmp=[cl.Buffer(self._ctx, mf.READ_WRITE, a_bytes) for _ in range(3)],
                partial=cl.Buffer(self._ctx, mf.READ_WRITE, n_groups * prog.acc.itemsize),
                total=cl.Buffer(self._ctx, mf.READ_WRITE, prog.acc.itemsize),
                n_groups=n_groups,
            )
            self._buffers[key] = b
        return b

    def _small(self, b: _Buffers, name: str, host: np.ndarray) -> "cl.Buffer":
        """Upload a small host array to a per-grid scratch buffer (grown when needed)."""
        entry = b.small.get(name)
        if entry is None or entry[1] < host.nbytes:
            entry = (cl.Buffer(self._ctx, cl.mem_flags.READ_ONLY, max(host.nbytes, 64)), max(host.nbytes, 64))
            b.small[name] = entry
        cl.enqueue_copy(self._queue, entry[0], host)  # blocking: host is a temporary
        return entry[0]

    def _meta(self, b: _Buffers, cstrides: tuple[int, ...]) -> "cl.Buffer":
        """``[ndim, shape, strides, cstrides]`` for the shift kernel (cached per grid)."""
        buf = b.meta.get(cstrides)
        if buf is None:
            host = np.array([len(b.shape), *b.shape, *_c_strides(b.shape), *cstrides], dtype=np.int32)
            buf = cl.Buffer(self._ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=host)
            b.meta[cstrides] = buf
        return buf

    def _taps(self, prog: _Program, exc: Sequence[np.ndarray], inh: Sequence[np.ndarray]):
        """Upload all taps as one buffer (kept while they do not change); (buffer, [(offset, len)])."""
        host = np.concatenate([np.asarray(t, dtype=np.float64).ravel() for t in (*exc, *inh)]).astype(prog.acc)
        key = prog.acc.str.encode() + bytes(str([len(t) for t in (*exc, *inh)]), "ascii") + host.tobytes()
        if key != self._taps_key:
            self._taps_buf = cl.Buffer(self._ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=host)
            offs, o = [], 0
            for t in (*exc, *inh):
                offs.append((o, len(t)))
                o += len(t)
            self._taps_layout = offs
            self._taps_key = key
        return self._taps_buf, self._taps_layout

    # ------------------------------------------------------------------ enqueueing
    def _launch(self, name: str, prog: _Program, size: int, *args, local: Optional[int] = None) -> None:
        """1-D launch over ``size`` items (padded to whole work-groups of ``local``)."""
        knl = prog.kernels[name]
        gsize = size if local is None else -(-size // local) * local
        knl(self._queue, (gsize,), None if local is None else (local,), *args)

    def _launch_axis(self, name: str, prog: _Program, shape: tuple[int, ...], axis: int, *args) -> None:
        """Launch a per-axis kernel (see ``AXIS_INDEX``); ``axis < 0`` is one flat axis of length 1."""
        if axis < 0:
            inner, n, outer = int(np.prod(shape)), 1, 1
        else:
            inner, n, outer = int(np.prod(shape[axis + 1:])), shape[axis], int(np.prod(shape[:axis]))
        if inner == 1:  # the last axis: work-items along it, where memory is contiguous
            gsize, s0, s2 = (n, outer, 1), n, 0
        else:  # work-items along the contiguous cells after the axis (measured fastest)
            gsize, s0, s2 = (inner, n, outer), 1, n * inner
        prog.kernels[name](self._queue, gsize, None, args[0], args[1], s0, s2, inner, *args[2:])

    def _enqueue_dynamics(self, prog, b, src_store: bool, exc, inh, phi: float) -> "cl.Buffer":
        """Excitation, inhibition, global inhibition and the total; returns the buffer of c."""
        taps, layout = self._taps(prog, exc, inh)
        nd = len(b.shape)
        strides = _c_strides(b.shape)
        t0, t1, t2 = b.tmp
        # excitation: act (storage) -> ... -> e; ping-pong between t0 and t1
        cur, cur_store = b.act, src_store
        outs = [t0, t1]
        for ax in range(nd):
            off, w = layout[ax]
            dst = outs[ax % 2]
            self._launch_axis("conv_store" if cur_store else "conv_acc", prog, b.shape, ax, cur, dst,
                              taps, off, w, w // 2)
            cur, cur_store = dst, False
        e = cur
        free = [t for t in (t0, t1, t2) if t is not e]
        # inhibition: e -> ... -> last pass fused with subtraction, threshold, partial sums
        src = e
        for ax in range(nd):
            off, w = layout[nd + ax]
            dst = free[ax % 2]
            if ax < nd - 1:
                self._launch_axis("conv_acc", prog, b.shape, ax, src, dst, taps, off, w, w // 2)
            else:
                self._launch("inhibit", prog, b.size, src, e, dst, taps, off, w, w // 2,
                             b.shape[ax], strides[ax], b.size, phi, b.partial,
                             cl.LocalMemory(self._wg * prog.acc.itemsize), local=self._wg)
            src = dst
        self._launch("sum_partials", prog, self._wg, b.partial, b.n_groups, b.total,
                     cl.LocalMemory(self._wg * prog.acc.itemsize), local=self._wg)
        return src

    @staticmethod
    def _shift_stages(shape, shift_axes, cond_shifts, uniform) -> list[list[tuple]]:
        """Host side of the shifts: stages (conditional, then uniform) of 1-axis passes.

        Each pass is ``(axis, cmode, ncond, cstrides, table)`` (see the shift kernel) with
        ``table[cond] = (floor(s) mod n, s - floor(s))``. As in the reference, each stage
        works in the accumulator type and stores its result in the grid's dtype; axes
        that do not move are skipped.
        """
        nd = len(shape)
        zero = (0,) * nd
        stages = []
        if cond_shifts is not None:
            axes = tuple(int(a) for a in shift_axes)
            cond_axes = [ax for ax in range(nd) if ax not in axes]
            cstr, ncond = [0] * nd, 1
            for ax in reversed(cond_axes):
                cstr[ax] = ncond
                ncond *= shape[ax]
            cmode = 1 if cond_axes == list(range(axes[-1] + 1, nd)) else 2
            sh = np.asarray(cond_shifts, dtype=np.float64).reshape(-1, len(axes))
            stages.append(
                [(ax, cmode, ncond, tuple(cstr), _split_table(sh[:, q], shape[ax])) for q, ax in enumerate(axes)]
            )
        if uniform is not None:
            u = np.asarray(uniform, dtype=np.float64)
            stage = [(ax, 0, 1, zero, _split_table(u[ax:ax + 1], shape[ax])) for ax in range(nd) if u[ax] != 0.0]
            if stage:
                stages.append(stage)
        return stages

    def _plan_shifts(self, prog, b, shift_axes, cond_shifts, uniform) -> tuple[list, "cl.Buffer"]:
        """The shift stages and their split table, uploaded before any kernel is enqueued
        (a write queued behind running kernels would wait for them). Without any stage a
        single copy pass remains (it normalises after the dynamics)."""
        stages = self._shift_stages(b.shape, shift_axes, cond_shifts, uniform)
        if not stages:
            stages = [[(-1, 0, 1, (0,) * len(b.shape), np.zeros((1, 2)))]]
        table = np.concatenate([p[-1].ravel() for stage in stages for p in stage]).astype(prog.acc)
        return stages, self._small(b, "table", table)

    def _enqueue_shifts(self, prog, b, src, src_store: bool, plan, normalise: bool) -> None:
        """Run the planned shift stages from ``src`` into ``b.res`` (grid dtype).

        With ``normalise`` the first pass divides by the total (and rounds to the grid
        dtype, as the reference stores the normalised activity). Each stage ends in the
        grid dtype: the last in ``b.res``, an earlier one in ``b.act`` (free once the
        dynamics have read it).
        """
        stages, tbuf = plan
        cur, cur_store, toff, first = src, src_store, 0, True
        for s_i, stage in enumerate(stages):
            for p_i, (axis, cmode, ncond, cstr, tab) in enumerate(stage):
                if p_i == len(stage) - 1:
                    dst, dst_store = (b.res if s_i == len(stages) - 1 else b.act), True
                else:
                    dst, dst_store = next(t for t in b.tmp if t is not cur), False
                name = f"shift_{'store' if cur_store else 'acc'}_{'store' if dst_store else 'acc'}"
                self._launch_axis(name, prog, b.shape, axis, cur, dst, cmode, ncond, self._meta(b, cstr),
                                  tbuf, toff, b.total, int(normalise and first))
                toff += tab.size
                cur, cur_store, first = dst, dst_store, False

    def _upload(self, b: _Buffers, a: np.ndarray) -> None:
        # blocking, like every upload here: they are queued before the kernels, so they
        # only wait for their own copy (pyopencl would block on the event anyway)
        cl.enqueue_copy(self._queue, b.act, np.ascontiguousarray(a))

    def _download(self, b: _Buffers, a: np.ndarray, out: Optional[np.ndarray]) -> np.ndarray:
        if out is None or not out.flags.c_contiguous:
            host = np.empty(a.shape, dtype=a.dtype)
            cl.enqueue_copy(self._queue, host, b.res)
            if out is None:
                return host
            out[...] = host
            return out
        cl.enqueue_copy(self._queue, out, b.res)
        return out

    def _total(self, prog, b) -> float:
        t = np.empty(1, dtype=prog.acc)
        cl.enqueue_copy(self._queue, t, b.total)
        return float(t[0])

    def _setup(self, a: np.ndarray):
        prog = self._program(np.dtype(a.dtype))
        return prog, self._bufs(tuple(a.shape), prog)

    # ----------------------------------------------------------------- the contract
    def dynamics(self, a, exc, inh, phi, out=None):
        prog, b = self._setup(a)
        self._upload(b, a)
        plan = self._plan_shifts(prog, b, None, None, None)
        c = self._enqueue_dynamics(prog, b, True, exc, inh, float(phi))
        self._enqueue_shifts(prog, b, c, False, plan, normalise=True)
        total = self._total(prog, b)
        if not (np.isfinite(total) and total > 0):
            return None
        return self._download(b, a, out)

    def shift(self, a, shifts, out=None):
        prog, b = self._setup(a)
        self._upload(b, a)
        self._enqueue_shifts(prog, b, b.act, True, self._plan_shifts(prog, b, None, None, shifts), normalise=False)
        return self._download(b, a, out)

    def shift_conditional(self, a, shift_axes, shifts, out=None):
        prog, b = self._setup(a)
        self._upload(b, a)
        plan = self._plan_shifts(prog, b, shift_axes, shifts, None)
        self._enqueue_shifts(prog, b, b.act, True, plan, normalise=False)
        return self._download(b, a, out)

    def inject(self, a, flat_index, values, out=None):
        """Scatter-add on the host: a few cells, and the result is needed on the host anyway."""
        res = a.copy() if out is None else out
        if out is not None:
            res[...] = a
        idx, vals = _injected_cells(a, flat_index, values)
        res.flat[idx] = vals
        return res

    def decode(self, a, window):
        """Population-vector decoding on the host (exactly :func:`population_vector_window`)."""
        return population_vector_window(a, window)

    def step(self, a, *, flat_index, values, exc, inh, phi, shift_axes, cond_shifts, uniform_shifts,
             window, out=None):
        """Fused iteration: one upload, every kernel enqueued, one read of the total and one download.

        Order as SPEC §1.2 and :meth:`Backend.step`: injection (the touched cells are
        computed on the host and written by ``scatter_set``), excitation, inhibition,
        global inhibition, normalisation (folded into the first shift pass), conditional
        shift, uniform shift; decoding on the downloaded grid.
        """
        prog, b = self._setup(a)
        self._upload(b, a)
        uni = uniform_shifts if uniform_shifts is not None and np.any(np.asarray(uniform_shifts) != 0) else None
        plan = self._plan_shifts(prog, b, shift_axes, cond_shifts, uni)
        if flat_index is not None and len(flat_index):
            idx, vals = _injected_cells(a, flat_index, values)
            ibuf = self._small(b, "inject_idx", idx.astype(np.int32))
            vbuf = self._small(b, "inject_val", vals)
            self._launch("scatter_set", prog, len(idx), b.act, ibuf, vbuf, len(idx))
        c = self._enqueue_dynamics(prog, b, True, exc, inh, float(phi))
        self._enqueue_shifts(prog, b, c, False, plan, normalise=True)
        total = self._total(prog, b)
        if not (np.isfinite(total) and total > 0):
            return None, None
        res = self._download(b, a, out)
        return res, population_vector_window(res, window)


# ----------------------------------------------------------------------------- helpers
def _pow2_floor(n: int) -> int:
    p = 1
    while p * 2 <= n:
        p *= 2
    return p


def _c_strides(shape: Sequence[int]) -> tuple[int, ...]:
    strides, acc = [], 1
    for n in reversed(shape):
        strides.append(acc)
        acc *= n
    return tuple(reversed(strides))


def _split_table(shifts: np.ndarray, n: int) -> np.ndarray:
    """``(floor(s) mod n, s - floor(s))`` per condition, shape (n_cond, 2), float64 (Fig 5.11)."""
    lo = np.floor(shifts)
    return np.stack([np.mod(lo, n), shifts - lo], axis=-1)


def _injected_cells(a: np.ndarray, flat_index, values) -> tuple[np.ndarray, np.ndarray]:
    """Distinct flat indices and their new values ``a + sum(values)`` (float64 sums, as numpy's add.at)."""
    fi = np.asarray(flat_index, dtype=np.int64).ravel()
    uniq, inv = np.unique(fi, return_inverse=True)
    acc = a.ravel()[uniq].astype(np.float64)
    np.add.at(acc, inv, np.asarray(values, dtype=np.float64).ravel())
    return uniq, acc.astype(a.dtype)
