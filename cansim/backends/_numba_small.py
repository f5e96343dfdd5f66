"""Fused numba step for small hypercube grids that the excitation kernel covers whole (e.g. 5^6).

When every excitation kernel is at least as wide as its axis, the locality box of the
generic pipeline (:mod:`cansim.backends._numba_kernels`) is the whole grid after the
first pass, so its box bookkeeping only costs time. For such ``n^d`` grids (``n`` at
most :data:`MAX_AXIS`) this module generates one compiled step per grid shape and
kernel widths whose line passes are unrolled over the axis length: each pass reads its
axis as the leading axis of the buffer (``n`` contiguous streams) and writes it as the
trailing one ("rotating" passes: after one pass per axis the buffer is back in C
order), with the tap positions baked into the code. An unrolled 5-cell, 5-tap pass
over 5^6 cells takes ~3 us against ~14 us for the generic table-driven pass. The step
(Alg 3-5, OpenRatSLAM's step order) is: inject, excitation and inhibition (Alg 3-4), global inhibition and
normalisation (Alg 5), heading-conditional then uniform fractional shifts (Fig 5.11),
and decoding (Eq 5.11-5.12), which for a window covering the grid is the circular mean
of the marginal sums, accumulated while the result is copied out.

The arithmetic is the numpy reference's (:mod:`cansim.backends.numpy_backend`):
float64 sums tap after tap in the reference's order, the fractional roll as
``(1 - f) * a[p - lo] + f * a[p - lo - 1]`` (plus exact zeros), and rounding to the
storage dtype where the reference stores (after injection, after the dynamics, after
the conditional shift, after the uniform shift; done as the values are stored, not in
passes of their own); the activity equals the generic numba pipeline's bit for bit. A
heading-conditional pass weights each line by its condition; the weights repeat along
the lines with a short period and come in runs (:func:`condition_runs`), so they are
filled run by run.

The generated functions are written as a module into the kernel cache folder and
compiled on first use with ``cache=True`` (:mod:`cansim.backends.kernel_cache`), so a
later process loads their machine code from disk; compiling them costs about 4 s for
the first storage dtype of a 6-D grid and 2 s for the other (once per grid shape,
kernel widths and cache folder). Only hypercubes take this path because every distinct
axis length adds its own unrolled kernels to compile.
"""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np
from numba import njit

from cansim.backends import _numba_kernels as _k
from whisker_io.numba_cache import tolerate_corrupt_cache

__all__ = ["MAX_AXIS", "MAX_TAPS", "applies", "small_step", "small_run", "plan_cycles", "condition_lines", "condition_runs"]

#: longest axis (cells) of a grid taking this path; passes are unrolled over it
MAX_AXIS = 8
#: widest tap array (cells) taking this path
MAX_TAPS = 9

_LOCK = threading.Lock()
_STEPS: dict = {}


def applies(shape: tuple[int, ...], exc, inh) -> bool:
    """Whether a grid of ``shape`` with these kernels takes the small full-grid path."""
    if len(shape) < 2 or max(shape) > MAX_AXIS or min(shape) != max(shape) or shape[0] < 2:
        return False  # hypercubes only: every distinct axis length costs seconds of compilation
    for n, e, i in zip(shape, exc, inh):
        if len(e) < n or len(e) > MAX_TAPS or len(i) > MAX_TAPS:
            return False
    return True


def condition_lines(shape: tuple[int, ...], shift_axes: tuple[int, ...]) -> np.ndarray:
    """Condition index of every line of every rotating pass, shape ``(ndim, size // min(shape))``.

    At pass k the lines run over the axes ``k+1, ..., d-1, 0, ..., k-1`` (C order); entry
    ``[k, r]`` is the C-order index over the non-shifted axes of line r.
    """
    d = len(shape)
    size = int(np.prod(shape))
    cond_axes = [ax for ax in range(d) if ax not in shift_axes]
    cstride = {}
    acc = 1
    for ax in reversed(cond_axes):
        cstride[ax] = acc
        acc *= shape[ax]
    res = np.zeros((d, size // min(shape)), np.int64)
    for k in range(d):
        order = [(k + 1 + t) % d for t in range(d - 1)]
        idx = np.indices([shape[ax] for ax in order]).reshape(d - 1, -1)
        g = np.zeros(idx.shape[1], np.int64)
        for row, ax in zip(idx, order):
            if ax in cstride:
                g += row * cstride[ax]
        res[k, : g.shape[0]] = g
    return res


def condition_runs(shape: tuple[int, ...], shift_axes: tuple[int, ...]) -> np.ndarray:
    """Structure of :func:`condition_lines`, shape ``(ndim, 2)``: ``[k] = (period, run)``.

    At pass k the condition index of line r depends only on ``r mod period`` (the lines
    over the axes from the first non-shifted one on, in the pass's order) and is the same
    over aligned runs of ``run`` lines (the axes after the last non-shifted one), so the
    per-line weights of a conditional pass are ``period`` columns built from
    ``period / run`` runs instead of one column per line.
    """
    d = len(shape)
    res = np.ones((d, 2), np.int64)
    for k in range(d):
        order = [(k + 1 + t) % d for t in range(d - 1)]
        cond = [i for i, ax in enumerate(order) if ax not in shift_axes]
        if cond:
            sizes = [shape[ax] for ax in order]
            res[k, 0] = int(np.prod(sizes[cond[0]:]))
            res[k, 1] = int(np.prod(sizes[cond[-1] + 1:]))
    return res


@njit(cache=True, nogil=True)
def plan_cycles(cond_tab, do_cond, shift_axes, uni, kinds, kinds2):
    """Plan the shift cycles of one step as the generic pipeline orders them; returns (ncycles, round_after).

    ``cond_tab`` is the step's (n_conditions, len(shift_axes)) table (read when
    ``do_cond``), ``uni`` its uniform shift per axis (zeros: none). Fills ``kinds`` (and
    ``kinds2`` for a second cycle) per axis: 0 none, 1 uniform, 2 conditional. One
    rotating cycle carries the conditional shift on its axes and the uniform shift on
    later axes (rounded to the storage dtype after the last conditional axis); when the
    uniform shift touches an earlier or a shifted axis, a conditional cycle runs first
    and a uniform one after it, as the reference orders them.
    """
    d = kinds.shape[0]
    kinds[:] = 0
    kinds2[:] = 0
    last_cond = -1
    if do_cond:
        for col in range(shift_axes.shape[0]):
            ax = shift_axes[col]
            for g in range(cond_tab.shape[0]):
                if cond_tab[g, col] != 0.0:
                    kinds[ax] = 2
                    last_cond = max(last_cond, ax)
                    break
    first_uni = -1
    for k in range(d - 1, -1, -1):
        if uni[k] != 0.0:
            first_uni = k
    ncycles = 0
    if first_uni >= 0 and last_cond >= 0 and (last_cond > first_uni or kinds[first_uni] != 0):
        ncycles = 2
        for k in range(d):
            if uni[k] != 0.0:
                kinds2[k] = 1
    else:
        for k in range(d):
            if uni[k] != 0.0:
                kinds[k] = 1
        for k in range(d):
            if kinds[k] != 0:
                ncycles = 1
    round_after = last_cond if first_uni >= 0 else -1
    return ncycles, round_after


@njit(cache=True, nogil=True)
def round32(buf):
    """Round every float64 cell to float32 and back (the reference's float32 store)."""
    for i in range(buf.shape[0]):
        buf[i] = np.float64(np.float32(buf[i]))


# ----------------------------------------------------------------- code generation
def _pass_src(header: str, preamble: list, n: int, term: Callable[[int, int], str], nterms: int) -> str:
    """A rotating pass over lines r: load the n cells of the line, ``dst[r, p] = sum_j term(p, j)``."""
    lines = [header] + preamble + ["    for r in range(rest):"]
    lines += [f"        x{q} = src[{q} * rest + r]" for q in range(n)]
    for p in range(n):
        lines.append(f"        dst[{n} * r + {p}] = " + " + ".join(term(p, j) for j in range(nterms)))
    return "\n".join(lines)


def _conv_src(n: int, nt: int) -> str:
    """Rotating periodic scatter convolution (Alg 3) along an axis of n cells, nt taps.

    Output p reads input ``p - (j - c)`` with tap j, summed tap after tap as the reference.
    """
    c = nt // 2
    return _pass_src(f"def conv_{n}_{nt}(src, dst, rest, w):", [f"    w{j} = w[{j}]" for j in range(nt)], n,
                     lambda p, j: f"w{j} * x{(p - (j - c)) % n}", nt)


def _lines_src(n: int) -> str:
    """Rotating fractional roll with per-line weights ``wl[s, r mod period]`` for a roll by s cells.

    The fractional roll of line r by ``lo + f`` (Fig 5.11) has weights ``1 - f`` at
    ``s = lo`` and ``f`` at ``s = lo + 1`` (mod n) and zero elsewhere; the sum runs over
    every s, so a line gets its own two products (in either order: the sum of two
    numbers does not depend on it) plus exact zeros. The weights repeat with the
    ``period`` of :func:`condition_runs`; ``r32`` rounds the result to float32 as it is
    stored (the reference's store after the conditional shift).
    """
    L = [f"def lines_{n}(src, dst, rest, wl, period, r32):"] + [f"    v{s} = wl[{s}]" for s in range(n)]
    L += ["    for o in range(rest // period):", "        b = o * period"]
    # slices, not offset indices: numba then drops its negative-index checks and the loops vectorise
    L += [f"        s{q} = src[{q} * rest + b:{q} * rest + b + period]" for q in range(n)]
    L += [f"        d = dst[{n} * b:{n} * (b + period)]"]
    for rounded in (True, False):  # one loop each: a test per line would stop the loop vectorising
        L += ["        if r32:" if rounded else "        else:", "            for j in range(period):"]
        L += [f"                x{q} = s{q}[j]" for q in range(n)]
        for p in range(n):
            y = " + ".join(f"v{s}[j] * x{(p - s) % n}" for s in range(n))
            L.append(f"                d[{n} * j + {p}] = " + (f"np.float64(np.float32({y}))" if rounded else y))
    return "\n".join(L)


def _marginals_src(shape: tuple[int, ...]) -> str:
    """Copy the float64 result to ``out`` and sum it over all axes but one, for every axis
    (``r32``: the result rounded to float32 first, the reference's store after the shifts)."""
    d = len(shape)
    size = int(np.prod(shape))
    L = ["def marginals(cur, out, prof, tmp, r32):"]
    src, m = "cur", size
    for k in range(d - 1, -1, -1):
        n = shape[k]
        dst = "tmp[:%d]" % (m // n) if k % 2 else "tmp[%d:%d]" % (size, size + m // n)
        L += [f"    p{q} = 0.0" for q in range(n)]
        L.append(f"    nxt{k} = {dst}")
        # the first level reads the result (rounded or not: one loop each, so that it vectorises)
        for rounded in ((True, False) if k == d - 1 else (None,)):
            ind = "    "
            if rounded is not None:
                L.append("    if r32:" if rounded else "    else:")
                ind = "        "
            L.append(f"{ind}for r in range({m // n}):")
            for q in range(n):
                x = f"np.float64({src}[{n} * r + {q}])"
                L.append(f"{ind}    x{q} = " + (f"np.float64(np.float32({x}))" if rounded else x))
                if k == d - 1:
                    L.append(f"{ind}    out[{n} * r + {q}] = x{q}")
                L.append(f"{ind}    p{q} += x{q}")
            L.append(f"{ind}    nxt{k}[r] = " + " + ".join(f"x{q}" for q in range(n)))
        L += [f"    prof[{k}, {q}] = p{q}" for q in range(n)]
        src, m = f"nxt{k}", m // n
    return "\n".join(L)


def _copy_src(n: int) -> str:
    """Rotating pass that only moves the leading axis to the end."""
    lines = [f"def copy_{n}(src, dst, rest):", "    for r in range(rest):"]
    lines += [f"        dst[{n} * r + {p}] = src[{p} * rest + r]" for p in range(n)]
    return "\n".join(lines)


def _width_call(n: int, widths: tuple[int, ...], indent: str, args: str, taps: str) -> list:
    """A call of the unrolled convolution of the width of axis k (a branch when widths differ)."""
    distinct = sorted(set(widths))
    if len(distinct) == 1:
        return [f"{indent}conv_{n}_{distinct[0]}({args}, {taps})"]
    lines = []
    for i, w in enumerate(distinct):
        cond = "else:" if i == len(distinct) - 1 else f"{'if' if i == 0 else 'elif'} widths[k] == {w}:"
        lines += [f"{indent}{cond}", f"{indent}    conv_{n}_{w}({args}, {taps})"]
    return lines


def _step_src(n: int, d: int, ew: tuple[int, ...], iw: tuple[int, ...]) -> str:
    """The step of an ``n^d`` grid: loops over the axes calling the unrolled passes."""
    size = n**d
    rest = size // n
    c = n // 2  # centre of the n-tap table of a uniform roll
    L = [
        "def cycle(src, dst, kinds, cond_tab, colmap, glines, lmeta, uni, round_after, to32):",
        "    ng = cond_tab.shape[0]",
        f"    gw = np.empty((ng, {n}), np.float64)",
        f"    wl = np.empty(({n}, {rest}), np.float64)",
        f"    taps = np.zeros({n}, np.float64)",
        f"    for k in range({d}):",
        "        if kinds[k] == 2:",
        "            for g in range(ng):",
        f"                lo, f = split_shift(cond_tab[g, colmap[k]], np.int64({n}))",
        f"                lo = lo % {n}",
        f"                for q in range({n}):",
        "                    gw[g, q] = 0.0",
        "                gw[g, lo] = 1.0 - f",
        f"                gw[g, (lo + 1) % {n}] = f",
        "            gl = glines[k]",
        "            period = lmeta[k, 0]",
        "            run = lmeta[k, 1]",
        "            for j0 in range(0, period, run):",
        "                g = gl[j0]",
        f"                for q in range({n}):",
        "                    val = gw[g, q]",
        "                    row = wl[q]",
        "                    for j in range(j0, j0 + run):",
        "                        row[j] = val",
        f"            lines_{n}(src, dst, {rest}, wl, period, to32 and round_after == k)",
        "        elif kinds[k] == 1:",
        f"            lo, f = split_shift(uni[k], np.int64({n}))",
        "            taps[:] = 0.0",
        f"            taps[(lo + {c}) % {n}] = 1.0 - f",
        f"            taps[(lo + 1 + {c}) % {n}] = f",
        f"            conv_{n}_{n}(src, dst, {rest}, taps)",
        "        else:",
        f"            copy_{n}(src, dst, {rest})",
        "        src, dst = dst, src",
        f"    return {d % 2 == 1}  # True: the result is in dst (an odd number of passes)",
        "",
        "def step(a, out, ws, fi, vals, exc, inh, phi, has_cond, cond_tab, colmap, glines, lmeta, shift_axes, uni,",
        "         window, decoded, to32):",
        f"    kinds1 = np.zeros({d}, np.int64)",
        f"    kinds2 = np.zeros({d}, np.int64)",
        "    ncycles, round_after = plan_cycles(cond_tab, has_cond, shift_axes, uni, kinds1, kinds2)",
        f"    x = ws[:{size}]",
        f"    y = ws[{size}:{2 * size}]",
        f"    z = ws[{2 * size}:{3 * size}]",
        f"    for i in range({size}):",
        "        x[i] = a[i]",
        "    for t in range(fi.shape[0]):",
        "        x[fi[t]] += vals[t]",
        "    if to32:  # the other cells hold float32 values already",
        "        for t in range(fi.shape[0]):",
        "            x[fi[t]] = np.float64(np.float32(x[fi[t]]))",
        "    src = x",
        "    dst = y",
        "    widths = ew",
        f"    for k in range({d}):",
    ]
    L += _width_call(n, ew, "        ", f"src, dst, {rest}", "exc[k]")
    L += ["        src, dst = dst, src"]
    # the excitation ends in x after an even number of passes
    e, f1, f2 = ("x", "y", "z") if d % 2 == 0 else ("y", "x", "z")
    t = f1 if (d - 1) % 2 == 0 else f2
    L += [
        f"    src = {e}",
        f"    dst = {f1}",
        "    widths = iw",
        f"    for k in range({d}):",
    ]
    L += _width_call(n, iw, "        ", f"src, dst, {rest}", "inh[k]")
    L += [
        "        if k % 2 == 0:",
        f"            src = {f1}",
        f"            dst = {f2}",
        "        else:",
        f"            src = {f2}",
        f"            dst = {f1}",
    ]
    L += [
        f"    total = global_inhibit({e}, {t}, {e}, {size}, phi)",
        "    if not (total > 0.0 and total < np.inf):",
        "        return False",
        "    if to32:",
        f"        for i in range({size}):",
        f"            {e}[i] = np.float64(np.float32({e}[i] / total))",
        "    else:",
        f"        for i in range({size}):",
        f"            {e}[i] = {e}[i] / total",
        f"    cur = {e}",
        "    if ncycles == 2:",
        f"        cur, other = {e}, z",
        "        if cycle(cur, other, kinds1, cond_tab, colmap, glines, lmeta, uni, np.int64(-1), to32):",
        f"            cur, other = z, {e}",
        "        if to32:",
        "            round32(cur)",
        "        if cycle(cur, other, kinds2, cond_tab, colmap, glines, lmeta, uni, np.int64(-1), to32):",
        "            cur = other",
        "    elif ncycles == 1:",
        f"        if cycle({e}, z, kinds1, cond_tab, colmap, glines, lmeta, uni, round_after, to32):",
        "            cur = z",
        "    # the last float32 store of the shifts happens as the result is copied out",
        f"    if 2 * window + 1 >= {n}:  # the window covers the grid: marginal sums",
        f"        prof = np.zeros(({d}, {n}), np.float64)",
        f"        marginals(cur, out, prof, np.empty({2 * size}, np.float64), to32)",
        f"        for k in range({d}):",
        f"            decoded[k] = circular_mean_index(prof[k], np.int64({n}))",
        "        return True",
        "    best = np.int64(0)",
        f"    for i in range({size}):",
        "        out[i] = cur[i]",
        "        if out[i] > out[best]:",
        "            best = i",
        "    n_arr = shape_arr.copy()  # writable: the generic kernels' variant (a global array is typed read-only)",
        "    decode_window(out, n_arr, unravel(best, n_arr), window, decoded)",
        "    return True",
    ]
    return "\n".join(L)


#: T steps in one call: the step of this shape, ping-ponging two buffers (see
#: :mod:`cansim.backends._numba_run`); returns -1, or the first step that collapsed
_RUN_SRC = """
def run(a, buf0, buf1, hist, record, ws, inj_off, inj_idx, inj_val, exc, inh, phi, has_cond, cond_tabs,
        colmap, glines, lmeta, shift_axes, unis, window, decoded, to32):
    src = a
    for t in range(decoded.shape[0]):
        dst = buf0 if t % 2 == 0 else buf1
        lo = inj_off[t]
        hi = inj_off[t + 1]
        if not step(src, dst, ws, inj_idx[lo:hi], inj_val[lo:hi], exc, inh, phi, has_cond[t], cond_tabs[t],
                    colmap, glines, lmeta, shift_axes, unis[t], window, decoded[t], to32):
            return t
        if record:
            hist[t, :] = dst
        src = dst
    return -1
"""


_HEADER = """\
# Generated by cansim.backends._numba_small for one grid shape and kernel widths; do not edit.
# (cansim.backends.kernel_cache: the file name holds the hash of this text and of its dependencies.)
import numpy as np
from numba import njit

from cansim.backends._numba_kernels import circular_mean_index, decode_window, global_inhibit, split_shift, unravel
from cansim.backends._numba_small import plan_cycles, round32

_OPTS = dict(cache={cache}, fastmath=False, nogil=True)
shape_arr = np.array({shape}, np.int64)
ew = np.array({ew}, np.int64)
iw = np.array({iw}, np.int64)
"""


def _decorated(src: str) -> str:
    return "\n\n@njit(**_OPTS)\n" + src.strip("\n") + "\n"


def module_source(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...], cache: bool = True) -> str:
    """Source of the module of one grid shape: the unrolled passes, the step and the run."""
    parts = []
    for n, w in sorted(set(zip(shape, ew)) | set(zip(shape, iw)) | {(n, n) for n in shape}):
        parts.append(_conv_src(n, w))
    for n in sorted(set(shape)):
        parts += [_lines_src(n), _copy_src(n)]
    parts.append(_marginals_src(shape))
    cycle, step = _step_src(shape[0], len(shape), ew, iw).split("\n\ndef step(")
    parts += [cycle, "def step(" + step, _RUN_SRC]
    head = _HEADER.format(cache=bool(cache), shape=list(shape), ew=list(ew), iw=list(iw))
    return head + "".join(_decorated(p) for p in parts)


def _build(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> dict:
    """The generated passes, step and run of one grid shape (lazily compiled), from the kernel cache.

    The module is written to the kernel cache folder and imported, so numba caches its
    machine code on disk (:mod:`cansim.backends.kernel_cache`); where that cannot be done
    the same source is compiled in memory for this process.
    """
    from cansim.backends import kernel_cache

    stem = "small_" + "x".join(map(str, shape)) + "_e" + "".join(map(str, ew)) + "_i" + "".join(map(str, iw))
    module = kernel_cache.cached_module(module_source(shape, ew, iw), stem, depends=(__file__, _k.__file__))
    if module is not None:
        return vars(module)
    ns: dict = {"__name__": "_cansim_kernels_in_memory"}
    exec(module_source(shape, ew, iw, cache=False), ns)  # noqa: S102 - generated from integers only
    return ns


def _compiled(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> dict:
    key = (shape, ew, iw)
    ns = _STEPS.get(key)
    if ns is None:
        with _LOCK:
            ns = _STEPS.get(key)
            if ns is None:
                ns = _build(shape, ew, iw)
                _STEPS[key] = ns
    return ns


def small_step(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> Callable:
    """The step for a grid shape and per-axis excitation/inhibition widths (generated once per process).

    Call as ``step(a, out, ws, fi, vals, exc, inh, phi, has_cond, cond_tab, colmap, glines,
    lmeta, shift_axes, uni, window, decoded, to32)`` with flat C-order ``a``/``out`` (storage
    dtype), a float64 workspace ``ws`` of >= 3 grid sizes, packed (ndim, width) tap arrays,
    the conditional shift table (read when ``has_cond``) with its axes, their columns
    (``colmap``), :func:`condition_lines` and :func:`condition_runs`, and the uniform shift
    per axis (zeros: none). The step plans its shift cycles with :func:`plan_cycles`. Returns
    False, with ``out`` untouched, when the dynamics collapse.
    """
    return _compiled(shape, ew, iw)["step"]


def small_run(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> Callable:
    """T steps of :func:`small_step` in one compiled call (generated once per process with it).

    Call as ``run(a, buf0, buf1, hist, record, ws, inj_off, inj_idx, inj_val, exc, inh, phi,
    has_cond, cond_tabs, colmap, glines, lmeta, shift_axes, unis, window, decoded, to32)``:
    per-step inputs have a leading step axis (injections in CSR form, ``cond_tabs`` (T,
    n_conditions, k) used where ``has_cond``, ``unis`` (T, ndim) with zeros for no shift), and
    the activity ping-pongs between ``buf0`` and ``buf1`` (``hist[t]`` gets step t's result
    when ``record``). Returns -1, or the first step whose dynamics collapsed.
    """
    return _compiled(shape, ew, iw)["run"]


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
