"""Per-whisk cost of Array.read_whisk_retrying against read_whisk (SimArray through the USB codec), alternately.

Usage: ``NUMBA_NUM_THREADS=1 python bench/whisk_retry_cost.py`` (no arguments). Prints the minimum ms per whisk of
each over 7 alternated rounds of 50 whisks and the median of the paired ratios.
"""
import time

from _script_args import script_args

script_args(__doc__, "NUMBA_NUM_THREADS=1 python bench/whisk_retry_cost.py (no arguments)")
import numpy as np
from whisker_io.hw.arm import SimArm
from whisker_io.hw.usb_array import SimArray

T, M = 2000, 18
def source(pose):
    s = np.zeros((T, M, 3)); s[:, :, 0] = np.linspace(-0.87, 0.87, T)[:, None]; return s
arm = SimArm()
arr = SimArray(source, arm.pose)
for _ in range(5):
    arr.read_whisk()
res = {"plain": [], "retrying": []}
for rep in range(7):
    for name, f in (("plain", arr.read_whisk), ("retrying", arr.read_whisk_retrying)) if rep % 2 == 0 else (("retrying", arr.read_whisk_retrying), ("plain", arr.read_whisk)):
        t = time.perf_counter()
        for _ in range(50):
            f()
        res[name].append((time.perf_counter() - t) / 50 * 1e3)
print({k: round(min(v), 4) for k, v in res.items()}, "ms per whisk (min of 7 x 50)")
print("median ratio retrying/plain:", round(float(np.median(np.array(res["retrying"]) / np.array(res["plain"]))), 4))
