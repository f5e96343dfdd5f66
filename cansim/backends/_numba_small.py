"""Fused numba step for small grids that the excitation kernel covers whole (e.g. 5^6).

When every excitation kernel is at least as wide as its axis, the locality box of the
generic pipeline (:mod:`cansim.backends._numba_kernels`) is the whole grid after the
first pass, so its box bookkeeping only costs time. For such grids (every axis at most
:data:`MAX_AXIS` cells) this module generates, per grid shape and kernel widths, one
compiled step whose line passes are unrolled over the axis length: each pass reads
its axis as the leading axis of the buffer (``n_k`` contiguous streams) and writes it
as the trailing one ("rotating" passes, so after one pass per axis the buffer is back
in C order), with the tap positions baked into the code. An unrolled 5-cell pass is
about 5x faster than the generic table-driven one.

The arithmetic is the numpy reference's (:mod:`cansim.backends.numpy_backend`):
float64 sums tap after tap in the reference's order, the fractional roll of Fig 5.11
as ``(1 - f) * a[p - lo] + f * a[p - lo - 1]``, and rounding to the storage dtype
where the reference stores (after injection, after the dynamics, after the
conditional shift, after the uniform shift).

The generated functions are compiled on first use in a process (they are built from
source text, which numba cannot cache on disk); a 6-D step compiles in a few seconds.
"""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np
from numba import njit

from cansim.backends import _numba_kernels as _k

__all__ = ["MAX_AXIS", "MAX_TAPS", "applies", "small_step", "condition_lines"]

#: longest axis (cells) of a grid taking this path; passes are unrolled over it
MAX_AXIS = 8
#: widest tap array (cells) taking this path
MAX_TAPS = 9

_OPTS = dict(cache=False, fastmath=False, nogil=True)
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


@njit(cache=True, nogil=True)
def round32(buf):
    """Round every float64 cell to float32 and back (the reference's float32 store)."""
    for i in range(buf.shape[0]):
        buf[i] = np.float64(np.float32(buf[i]))


# ----------------------------------------------------------------- code generation
def _conv_src(n: int, nt: int) -> str:
    """Rotating periodic scatter convolution (Alg 3) along an axis of n cells, nt taps."""
    c = nt // 2
    lines = [f"def conv_{n}_{nt}(src, dst, rest, w):"]
    lines += [f"    w{j} = w[{j}]" for j in range(nt)]
    lines.append("    for r in range(rest):")
    lines += [f"        x{q} = src[{q} * rest + r]" for q in range(n)]
    for p in range(n):
        terms = " + ".join(f"w{j} * x{(p - (j - c)) % n}" for j in range(nt))
        lines.append(f"        dst[{n} * r + {p}] = {terms}")
    return "\n".join(lines)


def _lines_src(n: int) -> str:
    """Rotating fractional roll with per-line weights ``wl[s, r]`` for a roll by s cells.

    The fractional roll of line r by ``lo + f`` (Fig 5.11) has weights ``1 - f`` at
    ``s = lo`` and ``f`` at ``s = lo + 1`` (mod n) and zero elsewhere; the sum runs over
    every s, so a line gets its own two products (in either order: the sum of two
    numbers does not depend on it) plus exact zeros.
    """
    lines = [f"def lines_{n}(src, dst, rest, wl):"]
    lines += [f"    v{s} = wl[{s}]" for s in range(n)]
    lines.append("    for r in range(rest):")
    lines += [f"        x{q} = src[{q} * rest + r]" for q in range(n)]
    for p in range(n):
        terms = " + ".join(f"v{s}[r] * x{(p - s) % n}" for s in range(n))
        lines.append(f"        dst[{n} * r + {p}] = {terms}")
    return "\n".join(lines)


def _marginals_src(shape: tuple[int, ...]) -> str:
    """Copy the float64 result to ``out`` and sum it over all axes but one, for every axis."""
    d = len(shape)
    size = int(np.prod(shape))
    L = ["def marginals(cur, out, prof, tmp):"]
    src, m = "cur", size
    for k in range(d - 1, -1, -1):
        n = shape[k]
        dst = "tmp[:%d]" % (m // n) if k % 2 else "tmp[%d:%d]" % (size, size + m // n)
        L += [f"    p{q} = 0.0" for q in range(n)]
        L.append(f"    nxt{k} = {dst}")
        L.append(f"    for r in range({m // n}):")
        for q in range(n):
            L.append(f"        x{q} = np.float64({src}[{n} * r + {q}])")
            if k == d - 1:
                L.append(f"        out[{n} * r + {q}] = x{q}")
            L.append(f"        p{q} += x{q}")
        L.append(f"        nxt{k}[r] = " + " + ".join(f"x{q}" for q in range(n)))
        L += [f"    prof[{k}, {q}] = p{q}" for q in range(n)]
        src, m = f"nxt{k}", m // n
    return "\n".join(L)


def _copy_src(n: int) -> str:
    """Rotating pass that only moves the leading axis to the end."""
    lines = [f"def copy_{n}(src, dst, rest):", "    for r in range(rest):"]
    lines += [f"        dst[{n} * r + {p}] = src[{p} * rest + r]" for p in range(n)]
    return "\n".join(lines)


def _step_src(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> str:
    d = len(shape)
    size = int(np.prod(shape))
    rest = [size // n for n in shape]
    L = [
        "def cycle(src, dst, kinds, cond_tab, colmap, glines, uni, round_after, to32):",
        "    ng = cond_tab.shape[0]",
        "    glo = np.empty(ng, np.int64)",
        "    gw = np.empty((ng, 2), np.float64)",
    ]
    for k, n in enumerate(shape):
        c = n // 2  # centre of the n-tap table of a uniform roll
        L += [
            f"    if kinds[{k}] == 2:",
            f"        wl = np.zeros(({n}, {rest[k]}), np.float64)",
            "        for g in range(ng):",
            f"            lo, f = split_shift(cond_tab[g, colmap[{k}]], {n})",
            f"            glo[g] = lo % {n}",
            "            gw[g, 0] = 1.0 - f",
            "            gw[g, 1] = f",
            f"        gl = glines[{k}]",
            f"        for r in range({rest[k]}):",
            "            g = gl[r]",
            "            wl[glo[g], r] = gw[g, 0]",
            f"            wl[(glo[g] + 1) % {n}, r] = gw[g, 1]",
            f"        lines_{n}(src, dst, {rest[k]}, wl)",
            f"    elif kinds[{k}] == 1:",
            f"        lo, f = split_shift(uni[{k}], {n})",
            f"        taps = np.zeros({n}, np.float64)",
            f"        taps[(lo + {c}) % {n}] = 1.0 - f",
            f"        taps[(lo + 1 + {c}) % {n}] = f",
            f"        conv_{n}_{n}(src, dst, {rest[k]}, taps)",
            "    else:",
            f"        copy_{n}(src, dst, {rest[k]})",
            f"    if round_after == {k} and to32:",
            "        round32(dst)",
            "    src, dst = dst, src",
        ]
    L += ["    if to32:", "        round32(src)", ""]
    L += [
        "def step(a, out, ws, fi, vals, exc, inh, phi, ncycles, kinds1, kinds2, cond_tab, colmap, glines, uni,",
        "         round_after, window, decoded, to32):",
        f"    x = ws[:{size}]",
        f"    y = ws[{size}:{2 * size}]",
        f"    z = ws[{2 * size}:{3 * size}]",
        f"    for i in range({size}):",
        "        x[i] = a[i]",
        "    if fi.shape[0] > 0:",
        "        for t in range(fi.shape[0]):",
        "            x[fi[t]] += vals[t]",
        "        if to32:",
        "            round32(x)",
    ]
    bufs = ["x", "y"]
    for k, n in enumerate(shape):
        L.append(f"    conv_{n}_{ew[k]}({bufs[0]}, {bufs[1]}, {rest[k]}, exc[{k}])")
        bufs.reverse()
    e = bufs[0]
    free = [b for b in ("x", "y", "z") if b != e]
    for k, n in enumerate(shape):
        L.append(f"    conv_{n}_{iw[k]}({free[0] if k else e}, {free[1] if k else free[0]}, {rest[k]}, inh[{k}])")
        if k:
            free.reverse()
    t = free[0]
    # a cycle of d rotating passes ends in its first buffer when d is even
    mid = e if d % 2 == 0 else "z"
    other = "z" if mid == e else e
    two = mid if d % 2 == 0 else other
    L += [
        f"    total = global_inhibit({e}, {t}, {e}, {size}, phi)",
        "    if not (total > 0.0 and total < np.inf):",
        "        return False",
        f"    for i in range({size}):",
        f"        {e}[i] = {e}[i] / total",
        "    if to32:",
        f"        round32({e})",
        f"    cur = {e}",
        "    if ncycles == 2:",
        f"        cycle({e}, z, kinds1, cond_tab, colmap, glines, uni, -1, to32)",
        f"        cycle({mid}, {other}, kinds2, cond_tab, colmap, glines, uni, -1, to32)",
        f"        cur = {two}",
        "    elif ncycles == 1:",
        f"        cycle({e}, z, kinds1, cond_tab, colmap, glines, uni, round_after, to32)",
        f"        cur = {mid}",
        f"    if 2 * window + 1 >= {max(shape)}:  # the window covers the grid: marginal sums",
        f"        prof = np.zeros(({d}, {max(shape)}), np.float64)",
        f"        marginals(cur, out, prof, np.empty({2 * size}, np.float64))",
        f"        for k in range({d}):",
        "            decoded[k] = circular_mean_index(prof[k], shape_arr[k])",
        "        return True",
        "    best = 0",
        f"    for i in range({size}):",
        "        out[i] = cur[i]",
        "        if out[i] > out[best]:",
        "            best = i",
        f"    decode_window(out, shape_arr, unravel(best, shape_arr), window, decoded)",
        "    return True",
    ]
    return "\n".join(L)


def _build(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> Callable:
    ns: dict = dict(np=np, split_shift=_k.split_shift, round32=round32, global_inhibit=_k.global_inhibit,
                    decode_window=_k.decode_window, circular_mean_index=_k.circular_mean_index, unravel=_k.unravel, shape_arr=np.array(shape, np.int64))
    parts = []
    for n, w in sorted(set(zip(shape, ew)) | set(zip(shape, iw)) | {(n, n) for n in shape}):
        parts.append(_conv_src(n, w))
    for n in sorted(set(shape)):
        parts += [_lines_src(n), _copy_src(n)]
    parts.append(_marginals_src(shape))
    for src in parts:
        exec(src, ns)  # noqa: S102 - generated from integers only
        name = src.split("(", 1)[0][4:]
        ns[name] = njit(**_OPTS)(ns[name])
    exec(_step_src(shape, ew, iw), ns)  # noqa: S102
    ns["cycle"] = njit(**_OPTS)(ns["cycle"])
    ns["step"] = njit(**_OPTS)(ns["step"])
    return ns["step"]


def small_step(shape: tuple[int, ...], ew: tuple[int, ...], iw: tuple[int, ...]) -> Callable:
    """The compiled step for a grid shape and per-axis excitation/inhibition widths (built once)."""
    key = (shape, ew, iw)
    fn = _STEPS.get(key)
    if fn is None:
        with _LOCK:
            fn = _STEPS.get(key)
            if fn is None:
                fn = _build(shape, ew, iw)
                _STEPS[key] = fn
    return fn
