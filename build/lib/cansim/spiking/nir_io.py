"""Export a spiking attractor population to NIR and import it back.

NIR (the Neuromorphic Intermediate Representation, https://neuroir.org) describes
continuous-time spiking graphs that Lava, Rockpool, snnTorch, Norse and SpiNNaker tools
read. :func:`to_nir` writes a LIF population as

``input -> input_scale (Scale) -> cells (CubaLIF) -> recurrent (Affine) -> cells``,
``cells -> output``

with every array flat over the grid in C order (``N`` cells):

* ``cells``: ``tau_syn = tau_syn_s``, ``tau_mem = tau_mem_s``, ``r = resistance``,
  ``v_threshold``, ``v_reset``, ``v_leak = v_rest + resistance * bias_current`` (NIR's
  CubaLIF has no bias; a constant bias current is a shift of the leak potential), and
  ``w_in = tau_syn``, so that a spike through a weight ``W`` raises the synaptic current
  by exactly ``W`` as in cansim (NIR: ``tau_syn dI/dt = -I + w_in S``);
* ``recurrent``: an ``N x N`` Affine node whose weight is
  ``w_rec * K(i - j) - w_global`` (the stationary, zero-velocity kernel of
  :mod:`cansim.spiking.connectivity`) and whose bias is 0;
* ``input_scale``: ``1 / tau_syn``, so that an input ``u`` on ``input`` is an external
  current ``u`` (threshold units) at steady state.

What NIR cannot carry is kept in ``graph.metadata["cansim"]``: the axes, the kernel
parameters, the refractory period (NIR's CubaLIF has none), the membrane noise, the
velocity lead table (the velocity-modulated kernel shift of path integration is a
multiplicative gating NIR cannot express, so the graph holds the stationary network),
the step ``dt_s`` and the seed. :func:`from_nir` rebuilds the population from the node
parameters and that metadata, checks that the Affine weights equal the kernels', and
so reproduces the original's spikes for the same seed.

NIR has no periodic convolution, so the connectivity is a dense Affine node and export
is limited to grids of at most ``max_dense_cells`` cells (default 4096).
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from cansim.axes import Axis
from cansim.errors import ConfigError
from cansim.params import AttractorParams
from cansim.spiking.neurons import NeuronParams
from cansim.spiking.population import SpikingParams, SpikingPopulation

__all__ = ["to_nir", "from_nir", "NIR_FORMAT"]

#: value of ``graph.metadata["cansim"]["format"]`` in graphs written by :func:`to_nir`
NIR_FORMAT = "cansim.spiking/1"


def _nir():
    try:
        import nir
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ConfigError("NIR export needs the 'nir' package: pip install 'cansim[spiking]'") from exc
    return nir


def _per_axis(value) -> np.ndarray:
    return np.atleast_1d(np.asarray(value, dtype=np.float64))


def to_nir(population: SpikingPopulation, *, max_dense_cells: int = 4096) -> Any:
    """A ``nir.NIRGraph`` of a LIF spiking population (see the module docstring for the layout).

    Parameters
    ----------
    population : SpikingPopulation
        A population of ``"lif"`` neurons.
    max_dense_cells : int
        Refuse grids with more cells (the Affine weight takes ``8 N^2`` bytes).

    Raises
    ------
    ConfigError
        Poisson neurons (NIR has no Poisson node) or a grid larger than ``max_dense_cells``.
    """
    nir = _nir()
    if not isinstance(population, SpikingPopulation):
        raise ConfigError("to_nir needs a cansim.spiking.SpikingPopulation")
    p = population.params
    nrn = p.neurons
    if nrn.model != "lif":
        raise ConfigError("NIR has no Poisson neuron; export a population with NeuronParams(model='lif')")
    n = population.size
    if n > max_dense_cells:
        raise ConfigError(
            f"the grid has {n} cells; its dense Affine weight would take {8 * n * n / 1e9:.1f} GB "
            f"(NIR has no periodic convolution). Raise max_dense_cells to export anyway"
        )
    ones = np.ones(n, dtype=np.float64)
    cells = nir.CubaLIF(
        tau_syn=nrn.tau_syn_s * ones,
        tau_mem=nrn.tau_mem_s * ones,
        r=nrn.resistance * ones,
        v_leak=(nrn.v_rest + nrn.resistance * nrn.bias_current) * ones,
        v_threshold=nrn.v_threshold * ones,
        v_reset=nrn.v_reset * ones,
        w_in=nrn.tau_syn_s * ones,
    )
    a = p.attractor
    meta = {
        "format": NIR_FORMAT,
        "grid_shape": np.array(population.shape, dtype=np.int64),
        "axis_names": ",".join(ax.name for ax in population.axes),
        "axis_steps": np.array([ax.step for ax in population.axes]),
        "axis_angular": np.array([int(ax.angular) for ax in population.axes], dtype=np.int64),
        "exc_width": _per_axis(a.exc_width),
        "exc_sigma": _per_axis(a.exc_sigma),
        "inh_width": _per_axis(a.inh_width),
        "inh_sigma": _per_axis(a.inh_sigma),
        "global_inhibition": float(a.global_inhibition),
        "kernel_normalisation": a.kernel_normalisation,
        "recurrent_weight": float(p.recurrent_weight),
        "global_weight": float(p.global_weight),
        "velocity_lead_s": float(p.velocity_lead_s),
        "lead_table": np.asarray(p.lead_table, dtype=np.float64).reshape(-1, 2),
        "v_rest": float(nrn.v_rest),
        "bias_current": float(nrn.bias_current),
        "refractory_s": float(nrn.refractory_s),
        "noise_sigma": float(nrn.noise_sigma),
        "poisson_gain_hz": float(nrn.poisson_gain_hz),
        "dt_s": float(population.dt_s),
        "seed": int(population.seed),
    }
    nodes = {
        "input": nir.Input(input_type={"input": np.array([n])}),
        "input_scale": nir.Scale(scale=ones / nrn.tau_syn_s),
        "cells": cells,
        "recurrent": nir.Affine(weight=population.kernel.dense_matrix(p.global_weight), bias=np.zeros(n)),
        "output": nir.Output(output_type={"output": np.array([n])}),
    }
    edges = [("input", "input_scale"), ("input_scale", "cells"), ("cells", "recurrent"), ("recurrent", "cells"), ("cells", "output")]
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata={"cansim": meta})


def _uniform(node: Any, name: str) -> float:
    arr = np.asarray(getattr(node, name), dtype=np.float64).ravel()
    if arr.size == 0 or not np.isfinite(arr).all() or np.any(arr != arr[0]):
        raise ConfigError(f"NIR node parameter {name!r} must be finite and the same for every cell")
    return float(arr[0])


def _scalar_or_tuple(arr: Any, cast=float):
    vals = [cast(x) for x in np.atleast_1d(np.asarray(arr)).ravel()]
    return vals[0] if len(vals) == 1 else tuple(vals)


def from_nir(graph: Any, *, dt_s: Optional[float] = None, seed: Optional[int] = None, backend: str = "numba") -> SpikingPopulation:
    """Rebuild a :class:`SpikingPopulation` from a graph written by :func:`to_nir`.

    Parameters
    ----------
    graph : nir.NIRGraph
        E.g. from ``nir.read(path)``.
    dt_s, seed : optional
        Override the step and seed stored in the metadata.
    backend : {"numpy", "numba"}

    Raises
    ------
    ConfigError
        The graph lacks cansim's metadata, its neuron or recurrent node is missing or
        malformed, its parameters differ between cells, or its Affine weights are not
        the kernels its metadata describes.
    """
    nir = _nir()
    if not isinstance(graph, nir.NIRGraph):
        raise ConfigError("from_nir needs a nir.NIRGraph (e.g. from nir.read)")
    meta = (graph.metadata or {}).get("cansim")
    if not isinstance(meta, dict) or str(meta.get("format", "")) != NIR_FORMAT:
        raise ConfigError(
            f"the graph carries no metadata['cansim'] of format {NIR_FORMAT!r}; "
            "only graphs written by cansim.spiking.to_nir can be imported"
        )
    cells = graph.nodes.get("cells")
    rec = graph.nodes.get("recurrent")
    if not isinstance(cells, nir.CubaLIF) or not isinstance(rec, nir.Affine):
        raise ConfigError("the graph needs a CubaLIF node 'cells' and an Affine node 'recurrent'")
    if ("cells", "recurrent") not in [tuple(e) for e in graph.edges] or ("recurrent", "cells") not in [tuple(e) for e in graph.edges]:
        raise ConfigError("the graph needs the recurrent loop cells -> recurrent -> cells")
    try:
        shape = tuple(int(x) for x in np.asarray(meta["grid_shape"]).ravel())
        names = str(meta["axis_names"]).split(",")
        steps = np.asarray(meta["axis_steps"], dtype=np.float64).ravel()
        angular = np.asarray(meta["axis_angular"]).ravel()
        axes = tuple(
            Axis(name=nm, size=sz, step=float(st), angular=bool(an)) for nm, sz, st, an in zip(names, shape, steps, angular)
        )
        if len(axes) != len(shape):
            raise ConfigError("metadata axis_names, grid_shape and axis_steps differ in length")
        attractor = AttractorParams(
            exc_width=_scalar_or_tuple(meta["exc_width"], lambda x: int(round(float(x)))),
            exc_sigma=_scalar_or_tuple(meta["exc_sigma"]),
            inh_width=_scalar_or_tuple(meta["inh_width"], lambda x: int(round(float(x)))),
            inh_sigma=_scalar_or_tuple(meta["inh_sigma"]),
            global_inhibition=float(meta["global_inhibition"]),
            kernel_normalisation=str(meta["kernel_normalisation"]),
        )
        tau_syn = _uniform(cells, "tau_syn")
        r = _uniform(cells, "r")
        if r <= 0:
            raise ConfigError(f"CubaLIF r (resistance) must be > 0, got {r}")
        v_rest = float(meta["v_rest"])
        if not np.allclose(np.asarray(cells.w_in, dtype=np.float64), tau_syn, rtol=1e-12, atol=0.0):
            raise ConfigError("CubaLIF w_in must equal tau_syn (cansim's current-jump convention)")
        v_leak = _uniform(cells, "v_leak")
        bias = float(meta.get("bias_current", np.nan))
        if not (np.isfinite(bias) and abs(v_rest + r * bias - v_leak) <= 1e-12 * max(1.0, abs(v_leak))):
            bias = (v_leak - v_rest) / r  # the node's leak potential wins over the metadata
        neurons = NeuronParams(
            model="lif",
            tau_mem_s=_uniform(cells, "tau_mem"),
            tau_syn_s=tau_syn,
            v_rest=v_rest,
            v_reset=_uniform(cells, "v_reset"),
            v_threshold=_uniform(cells, "v_threshold"),
            resistance=r,
            bias_current=bias,
            refractory_s=float(meta["refractory_s"]),
            noise_sigma=float(meta["noise_sigma"]),
            poisson_gain_hz=float(meta["poisson_gain_hz"]),
        )
        params = SpikingParams(
            attractor=attractor,
            neurons=neurons,
            recurrent_weight=float(meta["recurrent_weight"]),
            global_weight=float(meta["global_weight"]),
            velocity_lead_s=float(meta["velocity_lead_s"]),
            lead_table=tuple(map(tuple, np.asarray(meta["lead_table"], dtype=np.float64).reshape(-1, 2).tolist())),
        )
        pop = SpikingPopulation(
            axes,
            params,
            dt_s=float(meta["dt_s"]) if dt_s is None else dt_s,
            seed=int(meta["seed"]) if seed is None else seed,
            backend=backend,
        )
    except KeyError as exc:
        raise ConfigError(f"metadata['cansim'] lacks the entry {exc.args[0]!r}; re-export with cansim.spiking.to_nir") from None
    except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: int(inf), float(10**400)
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"malformed metadata['cansim']: {exc}") from None
    weight = np.asarray(rec.weight, dtype=np.float64)
    if weight.shape != (pop.size, pop.size):
        raise ConfigError(f"the Affine weight must have shape {(pop.size, pop.size)}, got {weight.shape}")
    expected = pop.kernel.dense_matrix(params.global_weight)
    if not np.allclose(weight, expected, rtol=1e-9, atol=1e-12) or np.any(np.asarray(rec.bias) != 0):
        raise ConfigError("the Affine weights are not the kernels of metadata['cansim']; the graph was edited")
    return pop
