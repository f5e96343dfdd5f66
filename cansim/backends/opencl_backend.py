"""OpenCL backend: pyopencl kernels for PoCL on CPUs and any OpenCL device elsewhere.

The kernels are the gather forms of the numpy reference (:mod:`cansim.backends.numpy_backend`):

* ``conv_*`` - one separable periodic 1-D pass (Alg 3/4). The reference scatters
  ``out[i + j - c] += a[i] * taps[j]`` with wrap-around; here every output cell gathers
  ``out[m] = sum_j taps[j] * a[m + c - j]`` (the reversed kernel), so no atomics are
  needed, taps longer than the axis wrap and add up exactly as ``np.roll`` sums do, and
  the taps are visited in the reference's order.
* ``inhibit`` - the last inhibition pass fused with ``b = e - e (*) I`` (Alg 4,
  OpenRatSLAM semantics) and global inhibition ``max(b - phi, 0)`` (Alg 5);
  ``row_sums`` adds each row of the whole grid (along its last axis) in index order and
  ``sum_partials`` reduces the row sums in a fixed order to the total for normalisation.
  The total is therefore the same bits whether a step computes the whole grid or a
  window of it (see *Locality*), and so is every result.
* ``shift_*`` - the fractional shift of Fig 5.7-5.11 along one axis, the reference's
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

Locality: :meth:`OpenCLBackend.step` and ``dynamics`` find on the host the shortest
circular interval per axis holding the active and injected cells, widen it by the
excitation half-width and the shifts of this step, and, when that window is at most half
the grid, compute only the window: its cut axes are not periodic and read zero beyond
their ends, which is exact because the activity there is zero (the reference adds
``tap * 0``). The result is written back into an otherwise zero grid. The total is summed
per row of the whole grid (cells outside the window count as the zeros they are), so a
windowed step equals the whole-grid step bit for bit.

Runs (:meth:`OpenCLBackend.run`): T steps are enqueued at once on the whole grid, with
every step's shift table and injection uploaded beforehand and injections added on the
device (``inject_add``, the same float64 sums as the host's); the activity after every
step is copied into a device history that is read back once per run (once per 64 MiB of
activity for long runs) and decoded on the host as :meth:`OpenCLBackend.step` decodes,
so a run equals T steps bit for bit.

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
install "cansim[opencl-intel]"``; cansim registers it with the ICD loader by itself
before pyopencl is imported (:func:`cansim.backends.opencl_runtime.register_icds`),
and the default device order puts it after the other devices, so it is used where
PoCL cannot build.

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

from cansim.backends.opencl_runtime import INTEL_PLATFORM_NAME, register_icds

#: what the ICD registration did (it must run before pyopencl lists platforms)
ICD_REGISTRATION = register_icds()

try:
    import pyopencl as cl  # noqa: E402
except ImportError:  # a base install: say what to install, not ModuleNotFoundError
    from cansim.errors import missing_extra as _missing_extra

    raise _missing_extra("the opencl backend (and list_devices)", "pyopencl", "opencl") from None

from cansim.backends.base import Backend, RunInputs, RunResult  # noqa: E402
from cansim.decoding import population_vector_window  # noqa: E402
from cansim.errors import BackendUnavailableError, InvalidInputError  # noqa: E402

__all__ = ["OpenCLBackend", "DEVICE_ENV_VAR", "list_devices"]

log = logging.getLogger(__name__)

#: environment variable naming the OpenCL device ("P:D" or a name substring)
DEVICE_ENV_VAR = "CANSIM_OPENCL_DEVICE"

#: device memory for the activity history of :meth:`OpenCLBackend.run` (bytes); a longer
#: run reads its history back once per this many bytes of activity
RUN_HISTORY_BYTES = 64 * 2**20

_INSTALL_HINT = (
    'pip install "cansim[opencl]" (pyopencl + PoCL, a CPU OpenCL platform), or "cansim[opencl-intel]" '
    "(Intel's CPU runtime) where PoCL cannot compile for the CPU"
)

_SOURCE = r"""
#ifdef NEED_FP64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif
#pragma OPENCL FP_CONTRACT OFF

/* Gather form of the periodic scatter convolution out[i + j - c] += in[i] * taps[j]
   along one axis (length n, element stride `stride`): out[m] = sum_j taps[j] in[m + c - j].
   On a cut-out axis (the *_cut kernels, wrap == 0, see the locality window) sources off
   the axis count 0; the reference adds taps[j] * 0 there, which leaves the sum unchanged.
   wrap is a compile-time constant in every kernel (a run-time flag stops vectorisation). */
#define CONV_GATHER(IN, coord, base, n, stride)                           \
    ACC s = 0;                                                            \
    if (wrap) {                                                           \
        int src = (coord + c) % n;                                        \
        for (int j = 0; j < w; ++j) {                                     \
            s += taps[toff + j] * (ACC)IN[base + src * stride];           \
            src = (src == 0) ? n - 1 : src - 1;                           \
        }                                                                 \
    } else {                                                              \
        for (int j = 0; j < w; ++j) {                                     \
            const int src = coord + c - j;                                \
            if (src >= 0 && src < n)                                      \
                s += taps[toff + j] * (ACC)IN[base + src * stride];       \
        }                                                                 \
    }

/* Per-axis NDRange over the cells after the axis (inner, stride st), on it (coord, n)
   and before it (outer): (inner, n, outer) with base = g0 + g2 * n * inner, so that
   neighbouring work-items read neighbouring memory; for the last axis (st == 1)
   (n, outer, 1) with base = g0 * n, work-items along the axis. No integer divisions. */
#define AXIS_INDEX                                                        \
    const int g0 = get_global_id(st == 1), coord = get_global_id(st != 1); \
    const int g2 = get_global_id(2), n = get_global_size(st != 1);        \
    const int base = g0 * s0 + g2 * s2;

#define CONV_KERNEL(NAME, IN_T, WRAP)                                     \
__kernel void NAME(__global const IN_T *in, __global ACC *out,            \
                   const int s0, const int s2, const int st,              \
                   __global const ACC *taps, const int toff, const int w, \
                   const int c)                                           \
{                                                                         \
    const int wrap = WRAP;                                                \
    AXIS_INDEX                                                            \
    CONV_GATHER(in, coord, base, n, st)                                   \
    out[base + coord * st] = s;                                           \
}

CONV_KERNEL(conv_store, T, 1)
CONV_KERNEL(conv_acc, ACC, 1)
CONV_KERNEL(conv_store_cut, T, 0)
CONV_KERNEL(conv_acc_cut, ACC, 0)

/* Last inhibition pass + b = e - e(*)I + global inhibition (Alg 4-5). */
#define INHIBIT_KERNEL(NAME, WRAP)                                        \
__kernel void NAME(__global const ACC *in, __global const ACC *e,         \
                   __global ACC *out,                                     \
                   __global const ACC *taps, const int toff, const int w, \
                   const int c, const int n, const int stride,            \
                   const int total,                                       \
                   const ACC phi)                                         \
{                                                                         \
    const int wrap = WRAP;                                                \
    const int gid = get_global_id(0);                                     \
    if (gid < total) {                                                    \
        const int coord = (gid / stride) % n;                             \
        const int base = gid - coord * stride;                            \
        CONV_GATHER(in, coord, base, n, stride)                           \
        const ACC b = e[gid] - s;                                         \
        out[gid] = (b >= phi) ? b - phi : (ACC)0;                         \
    }                                                                     \
}

INHIBIT_KERNEL(inhibit, 1)
INHIBIT_KERNEL(inhibit_cut, 0)

/* One partial sum per row (along the last axis) of the WHOLE grid, over the cells of a
   window of it: win = [n_0..n_{d-1} (grid), s_0.. (window start), m_0.. (window extent)].
   Work-item r is the grid's row r (C order of axes 0..d-2); a row outside the window
   sums to 0, a row inside adds its window cells in the grid's index order (the cells
   outside the window are zero, and x + 0 == x), so the partials, and the total that
   sum_partials makes of them, are the same bits for any window holding the activity. */
__kernel void row_sums(__global const ACC *cvals, __global ACC *partial, __global const int *win,
                       const int nd, const int nrows)
{
    const int r = get_global_id(0);
    if (r >= nrows) return;
    int rem = r, off = 0, wstride = win[3 * nd - 1], inside = 1;
    for (int ax = nd - 2; ax >= 0; --ax) {
        const int n = win[ax];
        const int coord = rem % n;
        rem /= n;
        int li = coord - win[nd + ax];  /* index in the window */
        if (li < 0) li += n;
        if (li >= win[2 * nd + ax]) inside = 0;
        off += li * wstride;
        wstride *= win[2 * nd + ax];
    }
    ACC s = 0;
    if (inside) {
        const int n = win[nd - 1], start = win[2 * nd - 1], m = win[3 * nd - 1];
        const int first_wrapped = n - start;  /* local index of the grid's cell 0, if the window wraps */
        for (int p = first_wrapped; p < m; ++p) s += cvals[off + p];
        for (int p = 0; p < m && p < first_wrapped; ++p) s += cvals[off + p];
    }
    partial[r] = s;
}

/* Device-side injection of a run: a[u] += the values of u in order, in ACC, rounded once
   (the host's np.add.at on float64 of OpenCLBackend.inject, for distinct indices u). */
__kernel void inject_add(__global T *a, __global const int *uidx, __global const int *voff,
                         __global const ACC *vals, const int base, const int m)
{
    const int i = get_global_id(0);
    if (i >= m) return;
    const int u = uidx[base + i];
    ACC acc = (ACC)a[u];
    for (int k = voff[base + i]; k < voff[base + i + 1]; ++k) acc += vals[k];
    a[u] = (T)acc;
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

/* Fractional shift along one axis (Fig 5.11): out[m] = (1 - f) in[m - lo] + f in[m - lo - 1]
   (wrapped; on a cut-out axis, the *_cut kernels, sources off the axis count 0 and lo
   is not reduced mod n), the same expression as the reference's _fractional_roll. NDRange as
   the convolution; n = 1 copies. The split of a cell is
   table[toff + 2 cond + {0, 1}] = (integer part mod n, fraction) for its condition
   index cond: 0 (cmode 0, uniform shift), i % ncond (cmode 1, the condition axes are the
   trailing ones) or sum_ax coord[ax] * cstride[ax] (cmode 2, any layout; meta = [ndim,
   shape, stride, cstride]). With use_norm every value read is first normalised by
   norm[0] and rounded to the storage type, as the reference stores the normalised
   activity. */
#define READ(IN, k) (use_norm ? (ACC)(T)((ACC)IN[k] / norm[0]) : (ACC)IN[k])
#define SHIFT_KERNEL(NAME, IN_T, OUT_T, WRAP)                             \
__kernel void NAME(__global const IN_T *in, __global OUT_T *out,          \
                   const int s0, const int s2, const int st,              \
                   const int cmode, const int ncond,                      \
                   __global const int *meta,                              \
                   __global const ACC *table, const int toff,             \
                   __global const ACC *norm, const int use_norm)          \
{                                                                         \
    const int wrap = WRAP;                                                \
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
    if (wrap && src < 0) src += n;                                        \
    ACC acc = (src >= 0 && src < n) ? READ(in, base + src * st) : (ACC)0; \
    if (f != 0) {                                                         \
        src = (wrap && src == 0) ? n - 1 : src - 1;                       \
        const ACC x1 = (src >= 0 && src < n)                              \
                       ? READ(in, base + src * st) : (ACC)0;              \
        acc = ((ACC)1 - f) * acc + f * x1;                                \
    }                                                                     \
    out[gid] = (OUT_T)acc;                                                \
}

SHIFT_KERNEL(shift_store_store, T, T, 1)
SHIFT_KERNEL(shift_store_acc, T, ACC, 1)
SHIFT_KERNEL(shift_acc_store, ACC, T, 1)
SHIFT_KERNEL(shift_acc_acc, ACC, ACC, 1)
SHIFT_KERNEL(shift_store_store_cut, T, T, 0)
SHIFT_KERNEL(shift_store_acc_cut, T, ACC, 0)
SHIFT_KERNEL(shift_acc_store_cut, ACC, T, 0)
SHIFT_KERNEL(shift_acc_acc_cut, ACC, ACC, 0)

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
        others = [(label, d) for label, d in usable if not d.type & cl.device_type.GPU]
        # the runtime cansim registered itself is the fallback: after PoCL and system drivers
        first = [d for label, d in others if not _registered_by_cansim(label)]
        return gpus + first + [d for label, d in others if _registered_by_cansim(label)], False
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


def _registered_by_cansim(label: str) -> bool:
    """A device label of :func:`list_devices` belongs to the Intel CPU runtime cansim registered (the fallback)."""
    platform = label.split(" ", 1)[1] if " " in label else label
    return ICD_REGISTRATION.vendors_dir is not None and platform.startswith(INTEL_PLATFORM_NAME + " /")


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
            'OpenCL runtime that knows it: pip install "cansim[opencl-intel]" (Intel\'s CPU runtime, '
            "which cansim registers by itself) or a newer PoCL"
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
    """Device buffers for one grid (and any smaller window of it) in one dtype."""

    capacity: int  # cells
    shape: tuple[int, ...]  # the whole grid
    act: "cl.Buffer"  # activity in storage dtype (input, injection target)
    res: "cl.Buffer"  # result in storage dtype
    tmp: list  # three accumulator-dtype grids
    partial: "cl.Buffer"  # one accumulator per row of the whole grid (along its last axis)
    total: "cl.Buffer"
    meta: dict = field(default_factory=dict)  # (shape, cstrides) -> cl.Buffer
    small: dict = field(default_factory=dict)  # name -> (cl.Buffer, nbytes)

    def grid(self, shape: tuple[int, ...], wraps: Optional[tuple[bool, ...]] = None,
             origin: Optional[tuple[int, ...]] = None) -> "_Grid":
        """These buffers seen as a grid of ``shape`` (at most ``capacity`` cells): the whole
        grid, or the window of it starting at cell ``origin`` (wrapping) with extents ``shape``."""
        shape = tuple(int(n) for n in shape)
        return _Grid(self, shape, int(np.prod(shape)), wraps or (True,) * len(shape),
                     tuple(int(o) for o in origin) if origin is not None else (0,) * len(shape))


@dataclass(frozen=True)
class _Grid:
    """A grid laid out in :class:`_Buffers`; ``wraps[ax]`` False for an axis cut to a window."""

    bufs: _Buffers
    shape: tuple[int, ...]
    size: int
    wraps: tuple[bool, ...]
    origin: tuple[int, ...]  # first cell of a window in the whole grid (zeros for the whole grid)

    def __getattr__(self, name):  # act, res, tmp, partial, total, meta, small
        return getattr(self.bufs, name)


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
    locality : bool
        In :meth:`step` and :meth:`dynamics`, compute only the window of cells the packet
        can reach in this step when that is at most half the grid (results are the
        same: the cells outside are zero); False always computes the whole grid.

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
    one per shifted axis, and one download. Launch and transfer overhead (tens of
    microseconds each on CPU runtimes) dominates small grids (a 360-cell ring,
    21 x 21 x 36). With ``locality`` one packet costs about the same on any grid size
    (on 61 x 61 x 36 the OpenRatSLAM packet needs a 16 x 17 x 15 window); the dense
    kernels pay off on large busy grids (10^6 cells), on every core and on GPUs.
    """

    name = "opencl"

    def __init__(
        self,
        device: Union[str, "cl.Device", None] = None,
        *,
        fp64: Optional[bool] = None,
        work_group: int = 64,
        locality: bool = True,
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
        self._locality = bool(locality)
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
                    " (this PoCL's LLVM does not know this CPU; install another OpenCL runtime: "
                    'pip install "cansim[opencl-intel]", or a newer PoCL, or pick a device with '
                    f"${DEVICE_ENV_VAR})"
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
        for cut in ("", "_cut"):
            for name in ("conv_store", "conv_acc"):
                kernels[name + cut].set_scalar_arg_dtypes([None, None, i32, i32, i32, None, i32, i32, i32])
            kernels["inhibit" + cut].set_scalar_arg_dtypes([None, None, None, None, i32, i32, i32, i32, i32, i32, acc])
            for name in ("shift_store_store", "shift_store_acc", "shift_acc_store", "shift_acc_acc"):
                kernels[name + cut].set_scalar_arg_dtypes(
                    [None, None, i32, i32, i32, i32, i32, None, None, i32, None, i32]
                )
        kernels["sum_partials"].set_scalar_arg_dtypes([None, i32, None, None])
        kernels["row_sums"].set_scalar_arg_dtypes([None, None, None, i32, i32])
        kernels["inject_add"].set_scalar_arg_dtypes([None, None, None, None, i32, i32])
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
            b = _Buffers(
                capacity=size,
                shape=shape,
                act=cl.Buffer(self._ctx, mf.READ_WRITE, s_bytes),
                res=cl.Buffer(self._ctx, mf.READ_WRITE, s_bytes),
                tmp=[cl.Buffer(self._ctx, mf.READ_WRITE, a_bytes) for _ in range(3)],
                partial=cl.Buffer(self._ctx, mf.READ_WRITE, max(size // shape[-1], 1) * prog.acc.itemsize),
                total=cl.Buffer(self._ctx, mf.READ_WRITE, prog.acc.itemsize),
            )
            self._buffers[key] = b
        return b

    def _small(self, g: "_Grid", name: str, host: np.ndarray) -> "cl.Buffer":
        """Upload a small host array to a scratch buffer of the grid (grown when needed)."""
        entry = g.small.get(name)
        if entry is None or entry[1] < host.nbytes:
            entry = (cl.Buffer(self._ctx, cl.mem_flags.READ_ONLY, max(host.nbytes, 64)), max(host.nbytes, 64))
            g.small[name] = entry
        cl.enqueue_copy(self._queue, entry[0], host)  # blocking: host is a temporary
        return entry[0]

    def _meta(self, g: "_Grid", cstrides: tuple[int, ...]) -> "cl.Buffer":
        """``[ndim, shape, strides, cstrides]`` for the shift kernel (cached; bounded)."""
        key = (g.shape, cstrides)
        buf = g.meta.get(key)
        if buf is None:
            if len(g.meta) > 256:  # windows change shape as the packet moves
                g.meta.clear()
            host = np.array([len(g.shape), *g.shape, *_c_strides(g.shape), *cstrides], dtype=np.int32)
            buf = cl.Buffer(self._ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=host)
            g.meta[key] = buf
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

    def _enqueue_dynamics(self, prog, g: "_Grid", exc, inh, phi: float) -> "cl.Buffer":
        """Excitation, inhibition, global inhibition and the total from ``g.act``; returns c's buffer."""
        taps, layout = self._taps(prog, exc, inh)
        nd = len(g.shape)
        strides = _c_strides(g.shape)
        t0, t1, t2 = g.tmp
        # excitation: act (storage) -> ... -> e; ping-pong between t0 and t1
        cur, cur_store = g.act, True
        for ax in range(nd):
            off, w = layout[ax]
            dst = (t0, t1)[ax % 2]
            name = ("conv_store" if cur_store else "conv_acc") + _cut(g.wraps[ax])
            self._launch_axis(name, prog, g.shape, ax, cur, dst, taps, off, w, w // 2)
            cur, cur_store = dst, False
        e = cur
        free = [t for t in (t0, t1, t2) if t is not e]
        # inhibition: e -> ... -> last pass fused with subtraction and threshold
        src = e
        for ax in range(nd):
            off, w = layout[nd + ax]
            dst = free[ax % 2]
            if ax < nd - 1:
                self._launch_axis("conv_acc" + _cut(g.wraps[ax]), prog, g.shape, ax, src, dst, taps, off, w, w // 2)
            else:
                self._launch("inhibit" + _cut(g.wraps[ax]), prog, g.size, src, e, dst, taps, off, w, w // 2,
                             g.shape[ax], strides[ax], g.size, phi)
            src = dst
        # the total: row sums of the whole grid, then one fixed-order reduction (window-independent)
        full = g.bufs.shape
        nrows = max(g.bufs.capacity // full[-1], 1)
        self._launch("row_sums", prog, nrows, src, g.partial, self._window_desc(g), nd, nrows)
        self._launch("sum_partials", prog, self._wg, g.partial, nrows, g.total,
                     cl.LocalMemory(self._wg * prog.acc.itemsize), local=self._wg)
        return src

    def _window_desc(self, g: "_Grid") -> "cl.Buffer":
        """``[whole-grid shape, window origin, window extents]`` for ``row_sums`` (cached; bounded)."""
        key = ("window", g.shape, g.origin)
        buf = g.meta.get(key)
        if buf is None:
            if len(g.meta) > 256:  # windows change as the packet moves
                g.meta.clear()
            host = np.array([*g.bufs.shape, *g.origin, *g.shape], dtype=np.int32)
            buf = cl.Buffer(self._ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=host)
            g.meta[key] = buf
        return buf

    def _plan_shifts(self, prog, g: "_Grid", shift_axes, cond_shifts, uniform) -> tuple[list, "cl.Buffer"]:
        """The shift stages of :func:`_shift_stages` and their split table, uploaded before
        any kernel is enqueued (a write queued behind running kernels would wait for them).
        Without any stage a single copy pass remains (it normalises after the dynamics)."""
        stages = _shift_stages(g.shape, g.wraps, shift_axes, cond_shifts, uniform)
        if not stages:
            stages = [[(-1, True, 0, 1, (0,) * len(g.shape), np.zeros((1, 2)))]]
        table = np.concatenate([p[-1].ravel() for stage in stages for p in stage]).astype(prog.acc)
        return stages, self._small(g, "table", table)

    def _enqueue_shifts(self, prog, g: "_Grid", src, src_store: bool, plan, normalise: bool, toff: int = 0) -> None:
        """Run the planned shift stages from ``src`` into ``g.res`` (grid dtype).

        With ``normalise`` the first pass divides by the total (and rounds to the grid
        dtype, as the reference stores the normalised activity). Each stage ends in the
        grid dtype: the last in ``g.res``, an earlier one in ``g.act`` (free once the
        dynamics have read it). ``toff`` is where the plan's split table starts in ``tbuf``.
        """
        stages, tbuf = plan
        cur, cur_store, first = src, src_store, True
        for s_i, stage in enumerate(stages):
            for p_i, (axis, wrap, cmode, ncond, cstr, tab) in enumerate(stage):
                if p_i == len(stage) - 1:
                    dst, dst_store = (g.res if s_i == len(stages) - 1 else g.act), True
                else:
                    dst, dst_store = next(t for t in g.tmp if t is not cur), False
                name = f"shift_{'store' if cur_store else 'acc'}_{'store' if dst_store else 'acc'}{_cut(wrap)}"
                self._launch_axis(name, prog, g.shape, axis, cur, dst, cmode, ncond, self._meta(g, cstr),
                                  tbuf, toff, g.total, int(normalise and first))
                toff += tab.size
                cur, cur_store, first = dst, dst_store, False

    def _upload(self, g: "_Grid", a: np.ndarray) -> None:
        # blocking, like every upload here: they are queued before the kernels, so they
        # only wait for their own copy (pyopencl would block on the event anyway)
        cl.enqueue_copy(self._queue, g.act, np.ascontiguousarray(a))

    def _download(self, g: "_Grid", dtype: np.dtype, out: Optional[np.ndarray]) -> np.ndarray:
        if out is None or not out.flags.c_contiguous:
            host = np.empty(g.shape, dtype=dtype)
            cl.enqueue_copy(self._queue, host, g.res)
            if out is None:
                return host
            out[...] = host
            return out
        cl.enqueue_copy(self._queue, out, g.res)
        return out

    def _total(self, prog, g: "_Grid") -> float:
        t = np.empty(1, dtype=prog.acc)
        cl.enqueue_copy(self._queue, t, g.total)
        return float(t[0])

    def _setup(self, a: np.ndarray):
        prog = self._program(np.dtype(a.dtype))
        return prog, self._bufs(tuple(a.shape), prog).grid(tuple(a.shape))

    def _iterate(self, a, out, injection, exc, inh, phi, shift_axes, cond_shifts, uniform) -> Optional[np.ndarray]:
        """Injection, dynamics and shifts (Alg 3-5, OpenRatSLAM's step order steps 1-6) on the device; the result or
        None when the dynamics collapse (``out`` is then left alone).

        When the activity and everything the step can spread it to fill at most half the
        grid, only that window is uploaded, computed (with the axes it cuts treated as
        zero beyond their ends, exact because the activity is zero there) and written
        back into an otherwise zero grid; otherwise the whole grid is.
        """
        prog, full = self._setup(a)
        fi = None if injection is None else np.asarray(injection[0], dtype=np.int64).ravel()
        win = None
        if self._locality:
            win = _locality_window(a, fi, exc, inh, shift_axes, cond_shifts, uniform)
        if win is None:
            g, sub, sub_cond, sub_fi = full, a, cond_shifts, fi
        else:
            idx, wraps = win
            sel = np.ix_(*idx)
            sub = a[sel]
            g = full.grid(sub.shape, wraps, origin=tuple(int(ix[0]) for ix in idx))
            sub_cond = None
            if cond_shifts is not None:
                cond_axes = [ax for ax in range(a.ndim) if ax not in tuple(shift_axes)]
                sub_cond = np.asarray(cond_shifts)[np.ix_(*[idx[ax] for ax in cond_axes])] if cond_axes else cond_shifts
            if fi is not None:
                coords = np.unravel_index(fi, a.shape)
                sub_fi = np.ravel_multi_index(
                    [(c - ix[0]) % n for c, ix, n in zip(coords, idx, a.shape)], sub.shape
                )
        self._upload(g, sub)
        plan = self._plan_shifts(prog, g, shift_axes, sub_cond, uniform)
        if fi is not None and len(fi):
            cells, vals = _injected_cells(sub, sub_fi, injection[1])
            ibuf = self._small(g, "inject_idx", cells.astype(np.int32))
            vbuf = self._small(g, "inject_val", vals)
            self._launch("scatter_set", prog, len(cells), g.act, ibuf, vbuf, len(cells))
        c = self._enqueue_dynamics(prog, g, exc, inh, float(phi))
        self._enqueue_shifts(prog, g, c, False, plan, normalise=True)
        total = self._total(prog, g)
        if not (np.isfinite(total) and total > 0):
            return None
        if win is None:
            return self._download(g, a.dtype, out)
        res = np.zeros(a.shape, dtype=a.dtype) if out is None else out
        if out is not None:
            res[...] = 0
        res[sel] = self._download(g, a.dtype, None)
        return res

    # ----------------------------------------------------------------- the contract
    def dynamics(self, a, exc, inh, phi, out=None):
        return self._iterate(a, out, None, exc, inh, phi, None, None, None)

    def shift(self, a, shifts, out=None):
        prog, g = self._setup(a)
        self._upload(g, a)
        self._enqueue_shifts(prog, g, g.act, True, self._plan_shifts(prog, g, None, None, shifts), normalise=False)
        return self._download(g, a.dtype, out)

    def shift_conditional(self, a, shift_axes, shifts, out=None):
        prog, g = self._setup(a)
        self._upload(g, a)
        plan = self._plan_shifts(prog, g, shift_axes, shifts, None)
        self._enqueue_shifts(prog, g, g.act, True, plan, normalise=False)
        return self._download(g, a.dtype, out)

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

        Order as Alg 3-5, OpenRatSLAM's step order and :meth:`Backend.step`: injection (the touched cells are
        computed on the host and written by ``scatter_set``), excitation, inhibition,
        global inhibition, normalisation (folded into the first shift pass), conditional
        shift, uniform shift; decoding on the downloaded grid. Only the window the packet
        can reach is computed when it is at most half the grid (see ``locality``).
        """
        injection = (flat_index, values) if flat_index is not None and len(flat_index) else None
        uni = uniform_shifts if uniform_shifts is not None and np.any(np.asarray(uniform_shifts) != 0) else None
        res = self._iterate(a, out, injection, exc, inh, phi, shift_axes, cond_shifts, uni)
        if res is None:
            return None, None
        return res, population_vector_window(res, window)


    def run(self, a, inputs: RunInputs, *, exc, inh, phi, window, record_activity=False) -> RunResult:
        """T steps enqueued at once on the device: one upload, one read-back per run.

        Every step's shift table and injection are prepared on the host and uploaded
        before the first kernel; each step then runs :meth:`step`'s kernels on the whole
        grid (a windowed step gives the same bits, see the module notes), adds its
        injection on the device (``inject_add``: the float64 sums of the host's), and
        copies its result and its total into device histories. The histories are read
        back once (long runs: once per :data:`RUN_HISTORY_BYTES` of activity), collapses
        are found from the totals, and every grid is decoded on the host as
        :meth:`step` decodes. The result equals T calls of :meth:`step` bit for bit.
        Without float64 intermediates (``fp64=False`` or a device without fp64) a run
        with injections takes :class:`Backend`'s step-by-step loop, since the host adds
        injections in float64.
        """
        a = np.ascontiguousarray(a)
        prog, g = self._setup(a)
        T = inputs.n_steps
        if prog.acc != np.dtype(np.float64) and len(inputs.inj_index):
            return super().run(a, inputs, exc=exc, inh=inh, phi=phi, window=window, record_activity=record_activity)
        nd = a.ndim
        # host side of every step: shift plans and tables, injections grouped by cell
        plans, tables, toffs, toff = [], [], [], 0
        inj_steps: list[tuple[int, int]] = []
        uidx, voff, ivals = [], [0], []
        for t in range(T):
            kw = inputs.step_kwargs(t)
            uni = kw["uniform_shifts"]
            if uni is not None and not np.any(np.asarray(uni) != 0):
                uni = None
            stages = _shift_stages(g.shape, g.wraps, kw["shift_axes"], kw["cond_shifts"], uni)
            if not stages:
                stages = [[(-1, True, 0, 1, (0,) * nd, np.zeros((1, 2)))]]
            table = np.concatenate([p[-1].ravel() for stage in stages for p in stage])
            plans.append(stages)
            tables.append(table)
            toffs.append(toff)
            toff += table.size
            fi, vals = kw["flat_index"], kw["values"]
            if fi is None:
                inj_steps.append((len(uidx), 0))
                continue
            uniq, inv = np.unique(np.asarray(fi, dtype=np.int64), return_inverse=True)
            order = np.argsort(inv, kind="stable")  # each cell's values in their given order, as np.add.at
            counts = np.bincount(inv, minlength=len(uniq))
            inj_steps.append((len(uidx), len(uniq)))
            uidx.extend(uniq.tolist())
            voff.extend((np.cumsum(counts) + len(ivals)).tolist())  # voff[p]..voff[p + 1]: the values of cell p
            ivals.extend(np.asarray(vals, dtype=np.float64)[order].tolist())
        mf = cl.mem_flags

        def upload(host):
            host = np.ascontiguousarray(host)
            return cl.Buffer(self._ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=host if host.size else np.zeros(1, host.dtype))

        tbuf = upload(np.concatenate(tables).astype(prog.acc))
        ubuf = upload(np.array(uidx, dtype=np.int32))
        obuf = upload(np.array(voff, dtype=np.int32))
        vbuf = upload(np.array(ivals, dtype=np.float64).astype(prog.acc))
        totals = cl.Buffer(self._ctx, mf.READ_WRITE, T * prog.acc.itemsize)
        nbytes = a.nbytes
        chunk = max(1, min(T, RUN_HISTORY_BYTES // max(nbytes, 1)))
        hist_dev = cl.Buffer(self._ctx, mf.READ_WRITE, chunk * nbytes)
        history = np.empty((T,) + a.shape, dtype=a.dtype) if record_activity else None
        block = np.empty((chunk,) + a.shape, dtype=a.dtype)
        decoded = np.empty((T, nd), dtype=np.float64)
        self._upload(g, a)
        for c0 in range(0, T, chunk):
            c1 = min(T, c0 + chunk)
            for t in range(c0, c1):
                base, m = inj_steps[t]
                if m:
                    self._launch("inject_add", prog, m, g.act, ubuf, obuf, vbuf, base, m)
                c = self._enqueue_dynamics(prog, g, exc, inh, float(phi))
                self._enqueue_shifts(prog, g, c, False, (plans[t], tbuf), normalise=True, toff=toffs[t])
                cl.enqueue_copy(self._queue, totals, g.total, byte_count=prog.acc.itemsize,
                                dst_offset=t * prog.acc.itemsize)
                cl.enqueue_copy(self._queue, g.act, g.res, byte_count=nbytes)
                cl.enqueue_copy(self._queue, hist_dev, g.res, byte_count=nbytes, dst_offset=(t - c0) * nbytes)
            cl.enqueue_copy(self._queue, block[: c1 - c0], hist_dev)  # reads as many bytes as the host slice holds
            for t in range(c0, c1):
                decoded[t] = population_vector_window(block[t - c0], window)
            if history is not None:
                history[c0:c1] = block[: c1 - c0]
        tot = np.empty(T, dtype=prog.acc)
        cl.enqueue_copy(self._queue, tot, totals)
        bad = np.flatnonzero(~(np.isfinite(tot) & (tot > 0)))
        if len(bad):
            return RunResult(None, None, None, int(bad[0]))
        return RunResult(block[(T - 1 - c0)].copy(), decoded, history, None)


# ----------------------------------------------------------------------------- helpers
def _pow2_floor(n: int) -> int:
    p = 1
    while p * 2 <= n:
        p *= 2
    return p


def _cut(wrap: bool) -> str:
    """Kernel name suffix of an axis cut to a window (not periodic)."""
    return "" if wrap else "_cut"


def _c_strides(shape: Sequence[int]) -> tuple[int, ...]:
    strides, acc = [], 1
    for n in reversed(shape):
        strides.append(acc)
        acc *= n
    return tuple(reversed(strides))


def _shift_stages(shape, wraps, shift_axes, cond_shifts, uniform) -> list[list[tuple]]:
    """Host side of the shifts: stages (conditional, then uniform) of 1-axis passes.

    Each pass is ``(axis, wrap, cmode, ncond, cstrides, table)`` (see the shift kernel)
    with ``table[cond] = (floor(s), s - floor(s))``, the integer part reduced mod n on
    periodic axes. As in the reference, each stage works in the accumulator type and
    stores its result in the grid's dtype; axes that do not move are skipped.
    """
    nd = len(shape)

    def split(ax, s):
        lo = np.floor(s)
        return np.stack([np.mod(lo, shape[ax]) if wraps[ax] else lo, s - lo], axis=-1)

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
        stages.append([(ax, wraps[ax], cmode, ncond, tuple(cstr), split(ax, sh[:, q])) for q, ax in enumerate(axes)])
    if uniform is not None:
        u = np.asarray(uniform, dtype=np.float64)
        stage = [(ax, wraps[ax], 0, 1, (0,) * nd, split(ax, u[ax:ax + 1])) for ax in range(nd) if u[ax] != 0.0]
        if stage:
            stages.append(stage)
    return stages


def _circular_cover(occupied: np.ndarray) -> tuple[int, int]:
    """Start and length of the shortest circular interval holding every True cell."""
    n = len(occupied)
    pos = np.flatnonzero(occupied)
    gaps = np.diff(np.append(pos, pos[0] + n)) - 1  # empty cells after each occupied one
    i = int(np.argmax(gaps))
    return int(pos[(i + 1) % len(pos)]), n - int(gaps[i])


def _locality_window(a, flat_index, exc, inh, shift_axes, cond_shifts, uniform):
    """The cells one step can touch, as per-axis index arrays and wrap flags, or None.

    Along each axis: the shortest circular interval holding the active (and injected)
    cells, widened by how far excitation and the shifts can carry activity (inhibition
    and global inhibition only lower it). An axis stays whole and periodic when the
    widened interval plus the farthest gather would wrap onto itself; the window is
    refused (None) when it covers more than half the grid or nothing is active.
    """
    nz = np.flatnonzero(a)
    if flat_index is not None and len(flat_index):
        nz = np.concatenate([nz, flat_index])
    if nz.size == 0 or 2 * nz.size > a.size:
        return None
    nd = a.ndim
    grow_lo = np.array([len(t) // 2 for t in exc])
    grow_hi = grow_lo.copy()
    gather = np.maximum(grow_lo, [len(t) // 2 for t in inh])
    moves = []
    if cond_shifts is not None:
        sh = np.asarray(cond_shifts, dtype=np.float64).reshape(-1, len(shift_axes))
        moves += [(ax, sh[:, q]) for q, ax in enumerate(shift_axes)]
    if uniform is not None:
        moves += [(ax, np.asarray(uniform, dtype=np.float64)[ax:ax + 1]) for ax in range(nd)]
    for ax, s in moves:
        lo = np.floor(s)
        grow_lo[ax] += max(0, int(-lo.min()))
        grow_hi[ax] += max(0, int(lo.max()) + 1)
        gather[ax] = max(gather[ax], int(np.abs(lo).max()) + 1)
    coords = np.unravel_index(nz, a.shape)
    idx, wraps, cells = [], [], 1
    for ax, n in enumerate(a.shape):
        occupied = np.zeros(n, dtype=bool)
        occupied[coords[ax]] = True
        start, length = _circular_cover(occupied)
        width = length + grow_lo[ax] + grow_hi[ax]
        if width + gather[ax] >= n:
            idx.append(np.arange(n))
            wraps.append(True)
        else:
            idx.append((start - grow_lo[ax] + np.arange(width)) % n)
            wraps.append(False)
        cells *= len(idx[-1])
    if all(wraps) or 2 * cells > a.size:
        return None
    return idx, tuple(wraps)


def _injected_cells(a: np.ndarray, flat_index, values) -> tuple[np.ndarray, np.ndarray]:
    """Distinct flat indices and their new values ``a + sum(values)`` (float64 sums, as numpy's add.at)."""
    fi = np.asarray(flat_index, dtype=np.int64).ravel()
    uniq, inv = np.unique(fi, return_inverse=True)
    acc = a.ravel()[uniq].astype(np.float64)
    np.add.at(acc, inv, np.asarray(values, dtype=np.float64).ravel())
    return uniq, acc.astype(a.dtype)
