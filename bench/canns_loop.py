"""canns' compiled loop on cansim's bench workloads; run with a Python that has canns installed.

Prints one JSON object: ``{workload: {"us_per_step": best of the repeats, ...}}`` for the
1-D ring (``CANN1D``) and the 2-D sheet (``CANN2D``), each in canns' dense ("normal") and
exact FFT accelerations, stepped ``--steps`` times inside ``bm.jit`` around
``bm.for_loop`` (canns' own idiom) with a per-step external input, returning the most
active cell per step. ``bench/test_bench_run.py`` runs it in canns' environment next to
cansim's ``Population.run`` and records the ratio; see bench/README.md. This file does not
import cansim and is not collected by pytest (no ``test_`` prefix).

Usage: ``python bench/canns_loop.py [--steps 1000] [--repeats 7] [--ring 360] [--sheet 32]``
"""

from __future__ import annotations

import argparse
import json
import time
import warnings


def _time(run, inputs, repeats: int) -> float:
    import jax

    jax.block_until_ready(run(inputs))  # compile
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run(inputs))
        best = min(best, time.perf_counter() - t0)
    return best


def _loop(model):
    import brainpy.math as bm

    def step(inp):
        model.update(inp)
        return bm.argmax(model.r.value)

    @bm.jit
    def run(inputs):
        return bm.for_loop(step, inputs, progress_bar=False)

    return run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--ring", type=int, default=360)
    ap.add_argument("--sheet", type=int, default=32)
    ap.add_argument("--only", default="", help="comma-separated workload names to run (default all)")
    args = ap.parse_args()

    import brainpy.math as bm
    import canns
    import jax
    import jax.numpy as jnp
    from canns.models.basic import CANN1D, CANN2D

    bm.set_dt(0.1)
    out = {"_versions": {"canns": canns.__version__, "jax": jax.__version__, "devices": str(jax.devices())}}
    only = {w for w in args.only.split(",") if w}
    for mode in ("normal", "fft"):
        name = f"ring{args.ring}-{mode}"
        if not only or name in only:
            m = CANN1D(num=args.ring)
            if mode == "fft":  # canns' documented set-up for an exact FFT ring
                m.x = bm.linspace(-bm.pi, bm.pi, args.ring, endpoint=False)
                m.conn_mat = m.make_conn()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    m.set_accl_mode("fft")
            stim = jnp.asarray(m.get_stimulus_by_pos(0.0))
            inputs = jnp.broadcast_to(stim, (args.steps,) + stim.shape) * 0.1
            out[name] = {"us_per_step": 1e6 * _time(_loop(m), inputs, args.repeats) / args.steps,
                         "accl_mode": m.accl_mode}
        name = f"sheet{args.sheet}-{mode}"
        if not only or name in only:
            m = CANN2D(length=args.sheet)
            if mode == "fft":
                m.x = bm.linspace(-bm.pi, bm.pi, args.sheet, endpoint=False)
                m.conn_mat = m.make_conn()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    m.set_accl_mode("fft")
            stim = jnp.asarray(m.get_stimulus_by_pos([0.0, 0.0]))
            inputs = jnp.broadcast_to(stim, (args.steps,) + stim.shape) * 0.1
            out[name] = {"us_per_step": 1e6 * _time(_loop(m), inputs, args.repeats) / args.steps,
                         "accl_mode": m.accl_mode}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
