"""Numba kernel of one spiking-population step; the same arithmetic, in the same order, as
``cansim.spiking.population._step_numpy`` (the reference), so both give identical spikes.

The kernel's weights come flat (C order) with their extent per grid axis (``kw``, 1 past
the weights' own axes), so one compiled specialisation serves populations of any number
of axes."""

from __future__ import annotations

import numba as nb
import numpy as np

from whisker_io.numba_cache import tolerate_corrupt_cache


@nb.njit(cache=True, nogil=True)
def step_kernel(
    v, i_syn, ref, pre, n_pre, wflat, kw, offset, shape, strides, rec,
    a_syn, b_syn, ext, g, v_rest, resistance, bias, a_mem, noise, noise_scale,
    v_threshold, v_reset, n_ref, poisson, gain_dt, out_spikes,
):  # pragma: no cover - compiled
    n = v.shape[0]
    nd = shape.shape[0]
    ksize = 1
    for a in range(nd):
        ksize *= kw[a]
    for c in range(n):
        rec[c] = 0.0
    coord = np.empty(nd, dtype=np.int64)
    idx = np.empty(nd, dtype=np.int64)
    for s in range(n_pre):
        p = pre[s]
        for a in range(nd - 1, -1, -1):
            coord[a] = p % shape[a]
            p //= shape[a]
        for a in range(nd):
            idx[a] = 0
        for k in range(ksize):
            t = 0
            for a in range(nd):
                x = (coord[a] + offset[a] + idx[a]) % shape[a]
                t += x * strides[a]
            rec[t] += wflat[k]
            a = nd - 1
            while a >= 0:
                idx[a] += 1
                if idx[a] < kw[a]:
                    break
                idx[a] = 0
                a -= 1
    has_ext = ext.shape[0] == n
    has_noise = noise.shape[0] == n
    count = 0
    for c in range(n):
        e = b_syn * ext[c] if has_ext else 0.0
        cur = a_syn * i_syn[c] + e + (rec[c] - g)
        i_syn[c] = cur
        if ref[c] > 0:
            ref[c] -= 1
            v[c] = v_reset
            continue
        if poisson:
            if noise[c] < gain_dt * max(cur + bias, 0.0):
                out_spikes[count] = c
                count += 1
                ref[c] = n_ref
            continue
        v_inf = v_rest + resistance * (cur + bias)
        vn = v_inf + (v[c] - v_inf) * a_mem
        if has_noise:
            vn = vn + noise_scale * noise[c]
        if vn > v_threshold:
            out_spikes[count] = c
            count += 1
            v[c] = v_reset
            ref[c] = n_ref
        else:
            v[c] = vn
    return count


tolerate_corrupt_cache(__name__)  # a corrupt numba cache file recompiles (whisker_io.numba_cache)
