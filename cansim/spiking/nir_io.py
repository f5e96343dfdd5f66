"""Export a spiking attractor population to NIR and import it back.

NIR (the Neuromorphic Intermediate Representation, https://neuroir.org) describes
continuous-time spiking graphs. :func:`to_nir` writes them in the conventions that the
NIR readers of snnTorch (``snntorch.import_nir.import_from_nir``), Norse
(``norse.torch.from_nir``) and Rockpool (``rockpool.nn.modules.torch.nir.from_nir``)
implement, so that each of them imports the graph as written and runs the same network
(``tests/test_nir_consumers.py`` checks this against cansim's own simulation).

Layout (every array flat over the grid in C order, ``N`` cells)::

    input -> current_in (Affine) -> cells (CubaLIF) -> output
                                    cells -> excitation (Linear) -> inhibition (Linear) -> cells

**Conventions the consumers implement, and what follows.** All three readers step the graph with a fixed step ``dt`` (snnTorch 1.0 hard-codes
``dt = 1e-4 s`` and asserts ``r = tau_mem / dt``; Norse takes ``dt`` as an argument;
Rockpool derives ``dt = tau_mem / (1 + r)``) and they read a neuron's output as ``1`` in a
step with a spike and ``0`` otherwise: a spike is a box of height 1 held for one step,
not a unit-area Dirac impulse. The graph is therefore written for one step
``dt_s`` (default :data:`NIR_STEP_S` ``= 1e-4`` s, stored in the metadata), and every
quantity below is exact for it. NIR's CubaLIF equations are

``tau_syn dI/dt = -I + w_in x``,   ``tau_mem dv/dt = (v_leak - v) + r I``,

with ``x`` the sum of the node's inputs. The conversions, with cansim's ``R``
(resistance), ``tau_mem``, ``tau_syn`` and ``dt = dt_s``:

* **time constants** ``tau_syn``, ``tau_mem``: copied (seconds).
* ``r = tau_mem / dt`` (snnTorch requires it): then Euler's membrane step is
  ``v <- (1 - dt/tau_mem) v + I``; ``w_in = tau_syn / dt``: then a box input ``x`` held
  for one step raises ``I`` by exactly ``w_in x dt / tau_syn = x``, the step snnTorch
  (``syn <- alpha syn + x``, its ``w_in dt / tau_syn = 1`` case, no threshold rescaling)
  and Rockpool (which ignores ``w_in``: ``isyn <- isyn + x``) take.
* **potentials** are shifted by ``v_rest``: ``v_leak = 0``, ``v_threshold - v_rest``,
  ``v_reset - v_rest`` (snnTorch and Norse need ``v_leak = 0`` and reset to 0, so a
  population whose ``v_reset`` differs from ``v_rest`` exports, but they run it with a
  reset to rest; a warning is logged).
* **current unit**: the graph's ``I_g`` is cansim's ``I`` times ``R dt / tau_mem``, since
  at rest ``v = r I_g`` must equal ``R I``.
* **recurrent weight** ``W`` (cansim's jump of ``I`` per presynaptic spike, the kernel of
  :mod:`cansim.spiking.connectivity`): ``I_g`` must jump by ``W R dt / tau_mem``, and a
  spike through a Linear weight ``w`` raises ``I_g`` by ``w`` (above), so the graph's
  recurrent matrix is ``W R dt / tau_mem``.
* **external and bias current** (cansim's ``I_ext`` and ``bias_current``, threshold
  units): a constant input ``x`` settles ``I_g`` at ``w_in x``; equating with
  ``I R dt / tau_mem`` gives ``x = I R dt^2 / (tau_mem tau_syn)``, so ``current_in`` is the
  Affine map ``R dt^2 / (tau_mem tau_syn) * (I_ext + bias_current)``: the graph's input is
  in cansim's threshold units. (cansim adds the bias to the current unfiltered; in the
  graph it passes the synapse, which changes only the first ``~tau_syn`` after a start.)
* **recurrent matrix, factored**: ``W = w_rec K - w_global 1 1^T`` with
  ``K = K_E * (delta_0 - K_I)`` equals ``M C_E`` where ``C_E`` is the circulant of the
  excitation kernel and ``M = w_rec (Id - C_I) - (w_global / s_E) 1 1^T``, ``s_E`` the
  sum of the excitation taps (circulants commute and ``1^T C_E = s_E 1^T``): the
  excitation-then-inhibition order of the rate model's step (Alg 4). ``excitation``
  holds ``C_E`` and ``inhibition`` holds ``M R dt / tau_mem``. The factoring is also
  what snnTorch needs: its reader rewrites a neuron <-> weight two-node loop into a
  recurrent cell whose *external* input it routes through the recurrent weight, so a
  two-node loop would multiply the input current by ``W``; a three-node loop is read
  as written. The product is checked against the kernel to ``1e-9`` on export.

What follows for a simulator that reads a spike as a unit-area impulse instead (the
strict reading of NIR's continuous-time semantics): each spike would act ``1 / dt``
times as strongly; the step in the metadata (``nir_step_s``) says which ``dt`` the
weights were written for.

What the graph cannot carry is kept in ``graph.metadata["cansim"]``: the axes, the kernel
parameters, the refractory period and membrane noise (the consumers' CubaLIF has
neither: a refractory period of one step, 0.1 ms, changes a rate of a few hundred Hz by
under 5 %; a longer one is dropped with a warning - a 2-ms period held the bump's cells
under 500 Hz in cansim, and without it they fired every step, a mean rate about 30 times
cansim's, though the bump's place and width held), the velocity lead table of the kernel-shift path
integration (a multiplicative gating with no NIR form; see
:mod:`cansim.spiking.rotation_ring` for path integration by neurons and synapses that
NIR carries), cansim's own step ``dt_s`` and the seed. :func:`from_nir` rebuilds the
population from the node parameters and that metadata and checks that the weights are
the kernels': the rebuilt population reproduces the original's spikes for the same seed.
Graphs of the first format (``cansim.spiking/1``, a Scale node and one Affine recurrent
node, spikes as jumps) are still read.

NIR has no periodic convolution, so the matrices are dense and export is limited to
grids of at most ``max_dense_cells`` cells (default 4096).
"""

from __future__ import annotations

import logging
import math
import warnings
from typing import Any, Optional

import numpy as np

from cansim.axes import Axis
from cansim.errors import ConfigError, missing_extra
from cansim.params import AttractorParams
from cansim.spiking.connectivity import RecurrentKernel
from cansim.spiking.neurons import NeuronParams
from cansim.spiking.population import SpikingParams, SpikingPopulation

__all__ = [
    "to_nir",
    "from_nir",
    "NIR_FORMAT",
    "NIR_STEP_S",
    "cuba_lif_node",
    "current_gain",
    "input_gain",
    "circulant",
    "factored_recurrent",
]

log = logging.getLogger(__name__)

#: value of ``graph.metadata["cansim"]["format"]`` in graphs written by :func:`to_nir`
NIR_FORMAT = "cansim.spiking/2"
#: the first format (Scale input, one Affine recurrent node, spikes as jumps); still read
NIR_FORMAT_V1 = "cansim.spiking/1"
#: the step (s) graphs are written for: snnTorch 1.0's hard-coded ``dt``
NIR_STEP_S = 1e-4
#: relative tolerance of the weight checks on export and import
WEIGHT_RTOL = 1e-9


def _nir():
    try:
        import nir
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise missing_extra("NIR export and import", "nir", "spiking") from exc
    return nir


def _per_axis(value) -> np.ndarray:
    return np.atleast_1d(np.asarray(value, dtype=np.float64))


def _check_step(dt_s: float, neurons: NeuronParams) -> float:
    try:
        dt = float(dt_s)
    except (TypeError, ValueError):
        raise ConfigError(f"dt_s must be a number of seconds, got {dt_s!r}") from None
    if not (math.isfinite(dt) and 0.0 < dt < min(neurons.tau_syn_s, neurons.tau_mem_s)):
        raise ConfigError(
            f"dt_s = {dt_s!r}: the consumers integrate with Euler steps, so the step must be > 0 and shorter than "
            f"tau_syn ({neurons.tau_syn_s} s) and tau_mem ({neurons.tau_mem_s} s); snnTorch always uses {NIR_STEP_S} s"
        )
    return dt


def current_gain(neurons: NeuronParams, dt_s: float) -> float:
    """``R dt / tau_mem``: the graph's synaptic current per unit of cansim's current (see the module docstring)."""
    return neurons.resistance * dt_s / neurons.tau_mem_s


def input_gain(neurons: NeuronParams, dt_s: float) -> float:
    """``R dt^2 / (tau_mem tau_syn)``: a graph input (an Affine output) per unit of cansim's current."""
    return neurons.resistance * dt_s * dt_s / (neurons.tau_mem_s * neurons.tau_syn_s)


def cuba_lif_node(neurons: NeuronParams, n: int, dt_s: float = NIR_STEP_S) -> Any:
    """The ``nir.CubaLIF`` of ``n`` cells of ``neurons`` written for the step ``dt_s`` (module docstring).

    Raises
    ------
    ConfigError
        Poisson neurons, or a step that is not > 0 and below both time constants.
    """
    nir = _nir()
    if neurons.model != "lif":
        raise ConfigError("NIR has no Poisson neuron; export a population with NeuronParams(model='lif')")
    dt = _check_step(dt_s, neurons)
    if neurons.v_reset != neurons.v_rest:
        log.warning(
            "v_reset (%g) differs from v_rest (%g): snnTorch, Norse and Rockpool reset to the leak potential",
            neurons.v_reset, neurons.v_rest,
        )
    ones = np.ones(int(n), dtype=np.float64)
    tau_mem, tau_syn = float(neurons.tau_mem_s), float(neurons.tau_syn_s)  # float64: r and w_in from the values written
    return nir.CubaLIF(
        tau_syn=tau_syn * ones,
        tau_mem=tau_mem * ones,
        r=(tau_mem / dt) * ones,
        v_leak=np.zeros(int(n)),
        v_threshold=(neurons.v_threshold - neurons.v_rest) * ones,
        v_reset=(neurons.v_reset - neurons.v_rest) * ones,
        w_in=(tau_syn / dt) * ones,
    )


def circulant(taps: np.ndarray, shape: tuple[int, ...], shift_cells: Optional[tuple[int, ...]] = None) -> np.ndarray:
    """Dense ``N x N`` matrix of a centred kernel on a periodic grid (post ``i``, pre ``j``, C order).

    Parameters
    ----------
    taps : ndarray, shape ``(w_0, ..., w_{d-1})``
        Kernel taps, centre at ``w // 2`` per axis.
    shape : tuple of int
        The grid.
    shift_cells : tuple of int, optional
        Move the kernel by whole cells per axis (a spike of cell ``j`` then reaches ``j + shift``).
    """
    taps = np.asarray(taps, dtype=np.float64)
    off = tuple(-(s // 2) + (int(shift_cells[a]) if shift_cells is not None else 0) for a, s in enumerate(taps.shape))
    return RecurrentKernel(taps, off, tuple(int(s) for s in shape)).folded().dense_matrix(0.0)


def factored_recurrent(params: SpikingParams, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``(C_E, M)`` with ``M @ C_E = w_rec K - w_global 1 1^T`` (the module docstring's factoring), cansim units."""
    a = params.attractor
    exc, inh = a.kernels(len(shape))
    ce = circulant(exc.dense(), shape)
    ci = circulant(inh.dense(), shape)
    s_e = float(np.sum(exc.dense()))
    if not s_e > 0:
        raise ConfigError("the excitation kernel sums to 0; the recurrent matrix cannot be factored")
    n = ce.shape[0]
    m = params.recurrent_weight * (np.eye(n) - ci) - (params.global_weight / s_e) * np.ones((n, n))
    return ce, m


def to_nir(population: SpikingPopulation, *, dt_s: float = NIR_STEP_S, max_dense_cells: int = 4096) -> Any:
    """A ``nir.NIRGraph`` of a LIF spiking population that snnTorch, Norse and Rockpool run as written.

    See the module docstring for the layout and every conversion. The graph's input is
    an external current per cell in cansim's threshold units (``SpikingPopulation.step``'s
    ``current``); its output is the cells' spikes.

    Parameters
    ----------
    population : SpikingPopulation
        A population of ``"lif"`` neurons.
    dt_s : float
        The step the consumers will use (s); snnTorch always uses :data:`NIR_STEP_S`.
    max_dense_cells : int
        Refuse grids with more cells (each matrix takes ``8 N^2`` bytes).

    Raises
    ------
    ConfigError
        Poisson neurons (NIR has no Poisson node), a grid larger than ``max_dense_cells``,
        or a bad step.
    """
    if not isinstance(population, SpikingPopulation):
        parts = [n for n in ("ring", "sheet") if isinstance(getattr(population, n, None), SpikingPopulation)]
        if parts:  # RatSLAM's spiking pose cells: two populations coupled in Python
            raise ConfigError(f"to_nir takes one SpikingPopulation; {type(population).__name__} holds "
                              f"{' and '.join(parts)}: export {', '.join('.' + n for n in parts)} one at a time "
                              "(the coupling between them, the velocity shifts and the view currents have no NIR form)")
        raise ConfigError(f"to_nir needs a cansim.spiking.SpikingPopulation, got {type(population).__name__}")
    nir = _nir()
    p = population.params
    nrn = p.neurons
    if nrn.model != "lif":
        raise ConfigError("NIR has no Poisson neuron; export a population with NeuronParams(model='lif')")
    n = population.size
    if n > max_dense_cells:
        raise ConfigError(
            f"the grid has {n} cells; its dense matrices would take {16 * n * n / 1e9:.1f} GB "
            f"(NIR has no periodic convolution). Raise max_dense_cells to export anyway"
        )
    dt = _check_step(dt_s, nrn)
    if nrn.refractory_s > dt * (1 + 1e-9):
        warnings.warn(
            f"to_nir: NIR's CubaLIF has no refractory period, so the graph drops this population's "
            f"{nrn.refractory_s * 1e3:g} ms: in snnTorch, Norse or Rockpool its cells can fire every step "
            f"({1 / dt:g} Hz) where cansim's fire at most {1 / nrn.refractory_s:g} Hz, and a bump's cells fire "
            "many times faster (the bump's place and width hold; from_nir restores the period from the metadata). "
            f"For the same rates export NeuronParams(refractory_s={dt:g}) or less", UserWarning, stacklevel=2)
    if dt != NIR_STEP_S:
        warnings.warn(f"to_nir: dt_s = {dt:g} s; snnTorch runs every graph at {NIR_STEP_S} s and refuses this one "
                      "(Norse and Rockpool take the step given)", UserWarning, stacklevel=2)
    ce, m = factored_recurrent(p, population.shape)
    target = population.kernel.dense_matrix(p.global_weight)
    scale = max(float(np.abs(target).max()), float((np.abs(m) @ np.abs(ce)).max()), p.recurrent_weight + p.global_weight, 1e-300)
    if not np.allclose(m @ ce, target, rtol=0.0, atol=WEIGHT_RTOL * scale):  # pragma: no cover - algebra
        raise ConfigError("internal: the factored recurrent matrix differs from the kernel")
    g_in = input_gain(nrn, dt)
    a = p.attractor
    meta = {
        "format": NIR_FORMAT,
        "nir_step_s": dt,
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
        # exact copies of what the nodes hold converted (from_nir prefers them where they agree)
        "v_reset": float(nrn.v_reset),
        "v_threshold": float(nrn.v_threshold),
        "resistance": float(nrn.resistance),
        "bias_current": float(nrn.bias_current),
        "refractory_s": float(nrn.refractory_s),
        "noise_sigma": float(nrn.noise_sigma),
        "poisson_gain_hz": float(nrn.poisson_gain_hz),
        "dt_s": float(population.dt_s),
        "seed": int(population.seed),
    }
    nodes = {
        "input": nir.Input(input_type={"input": np.array([n])}),
        "current_in": nir.Affine(weight=g_in * np.eye(n), bias=np.full(n, g_in * nrn.bias_current)),
        "cells": cuba_lif_node(nrn, n, dt),
        "excitation": nir.Linear(weight=ce),
        "inhibition": nir.Linear(weight=m * current_gain(nrn, dt)),
        "output": nir.Output(output_type={"output": np.array([n])}),
    }
    edges = [
        ("input", "current_in"),
        ("current_in", "cells"),
        ("cells", "excitation"),
        ("excitation", "inhibition"),
        ("inhibition", "cells"),
        ("cells", "output"),
    ]
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata={"cansim": meta})


def _uniform(node: Any, name: str) -> float:
    try:
        arr = np.asarray(getattr(node, name), dtype=np.float64).ravel()
    except (TypeError, ValueError, AttributeError):
        raise ConfigError(f"NIR node parameter {name!r} must be an array of numbers") from None
    if arr.size == 0 or not np.isfinite(arr).all() or np.any(arr != arr[0]):
        raise ConfigError(f"NIR node parameter {name!r} must be finite and the same for every cell")
    return float(arr[0])


def _scalar_or_tuple(arr: Any, cast=float):
    vals = [cast(x) for x in np.atleast_1d(np.asarray(arr)).ravel()]
    return vals[0] if len(vals) == 1 else tuple(vals)


def _axes_from_meta(meta: dict) -> tuple[Axis, ...]:
    shape = tuple(int(x) for x in np.asarray(meta["grid_shape"]).ravel())
    names = str(meta["axis_names"]).split(",")
    steps = np.asarray(meta["axis_steps"], dtype=np.float64).ravel()
    angular = np.asarray(meta["axis_angular"]).ravel()
    if not (len(names) == len(shape) == len(steps) == len(angular)):
        raise ConfigError("metadata axis_names, grid_shape, axis_steps and axis_angular differ in length")
    return tuple(Axis(name=nm, size=sz, step=float(st), angular=bool(an)) for nm, sz, st, an in zip(names, shape, steps, angular))


def _attractor_from_meta(meta: dict) -> AttractorParams:
    return AttractorParams(
        exc_width=_scalar_or_tuple(meta["exc_width"], lambda x: int(round(float(x)))),
        exc_sigma=_scalar_or_tuple(meta["exc_sigma"]),
        inh_width=_scalar_or_tuple(meta["inh_width"], lambda x: int(round(float(x)))),
        inh_sigma=_scalar_or_tuple(meta["inh_sigma"]),
        global_inhibition=float(meta["global_inhibition"]),
        kernel_normalisation=str(meta["kernel_normalisation"]),
    )


def _spiking_params(meta: dict, attractor: AttractorParams, neurons: NeuronParams) -> SpikingParams:
    return SpikingParams(
        attractor=attractor,
        neurons=neurons,
        recurrent_weight=float(meta["recurrent_weight"]),
        global_weight=float(meta["global_weight"]),
        velocity_lead_s=float(meta["velocity_lead_s"]),
        lead_table=tuple(map(tuple, np.asarray(meta["lead_table"], dtype=np.float64).reshape(-1, 2).tolist())),
    )


def _prefer(meta: dict, key: str, from_nodes: float) -> float:
    """The metadata's exact value where it agrees with the nodes' (to rounding), else the nodes'."""
    try:
        exact = float(meta.get(key, math.nan))
    except (TypeError, ValueError):
        return from_nodes
    if math.isfinite(exact) and math.isclose(exact, from_nodes, rel_tol=1e-9, abs_tol=1e-12):
        return exact
    return from_nodes


def _edge_set(graph: Any) -> set:
    try:
        return {tuple(e) for e in graph.edges}
    except TypeError:
        raise ConfigError("the graph's edges must be (source, target) pairs") from None


def from_nir(
    graph: Any,
    *,
    dt_s: Optional[float] = None,
    seed: Optional[int] = None,
    backend: str = "numba",
    metadata: Optional[dict] = None,
) -> SpikingPopulation:
    """Rebuild a :class:`SpikingPopulation` from a graph written by :func:`to_nir`.

    Parameters
    ----------
    graph : nir.NIRGraph
        E.g. from ``nir.read(path)``; of format :data:`NIR_FORMAT` or the first format.
    dt_s, seed : optional
        Override cansim's step and the seed stored in the metadata.
    backend : {"numpy", "numba"}
    metadata : dict, optional
        ``metadata["cansim"]`` of the graph cansim wrote, for a graph that lost it: one a
        consumer wrote back for the same network (e.g. Rockpool's ``to_nir`` after its
        ``from_nir``). Such a graph is accepted when its nodes and edges are the network
        described here. (What the consumers write back was tried: snnTorch 1.0's
        ``export_to_nir`` fails on the module its reader built; Norse 1.1's ``to_nir``
        writes untyped nodes and Rockpool 3.1's drops the ``inhibition -> cells`` edge and
        rewrites ``r``, so those graphs are refused with the missing edge named.)

    Raises
    ------
    ConfigError
        The graph lacks cansim's metadata, a node is missing or malformed, its parameters
        differ between cells or break the conventions of the module docstring, or its
        weights are not the kernels its metadata describes.

    See Also
    --------
    cansim.spiking.nir_graph_sim.NIRGraphSimulator : simulates any graph of this layout
        (and the path-integrating ring), with or without cansim's metadata.
    """
    nir = _nir()
    if not isinstance(graph, nir.NIRGraph):
        raise ConfigError("from_nir needs a nir.NIRGraph (e.g. from nir.read)")
    meta = (graph.metadata or {}).get("cansim") if isinstance(graph.metadata, dict) else None
    if meta is None and metadata is not None:
        meta = metadata
    fmt = str(meta.get("format", "")) if isinstance(meta, dict) else ""
    if fmt == NIR_FORMAT_V1:
        return _from_nir_v1(graph, meta, dt_s, seed, backend)
    if fmt != NIR_FORMAT:
        raise ConfigError(
            f"the graph carries no metadata['cansim'] of format {NIR_FORMAT!r}; "
            "only graphs written by cansim.spiking.to_nir can be rebuilt as a SpikingPopulation "
            "(cansim.spiking.NIRGraphSimulator runs other graphs of the same layout)"
        )
    nodes = graph.nodes
    cells, cin = nodes.get("cells"), nodes.get("current_in")
    exc, inh = nodes.get("excitation"), nodes.get("inhibition")
    if not (
        isinstance(cells, nir.CubaLIF) and isinstance(cin, nir.Affine)
        and isinstance(exc, nir.Linear) and isinstance(inh, nir.Linear)
    ):
        raise ConfigError("the graph needs a CubaLIF 'cells', an Affine 'current_in' and Linear 'excitation' and 'inhibition'")
    edges = _edge_set(graph)
    for e in (("current_in", "cells"), ("cells", "excitation"), ("excitation", "inhibition"), ("inhibition", "cells")):
        if e not in edges:
            raise ConfigError(f"the graph lacks the edge {e[0]} -> {e[1]} of the layout cansim writes")
    try:
        axes = _axes_from_meta(meta)
        attractor = _attractor_from_meta(meta)
        step = float(meta["nir_step_s"])
        if not (math.isfinite(step) and step > 0):
            raise ConfigError(f"metadata nir_step_s must be a positive number of seconds, got {meta['nir_step_s']!r}")
        tau_syn, tau_mem = _uniform(cells, "tau_syn"), _uniform(cells, "tau_mem")
        if not (tau_syn > 0 and tau_mem > 0):
            raise ConfigError("CubaLIF tau_syn and tau_mem must be > 0")
        r, w_in = _uniform(cells, "r"), _uniform(cells, "w_in")
        if not (math.isclose(r, tau_mem / step, rel_tol=1e-9) and math.isclose(w_in, tau_syn / step, rel_tol=1e-9)):
            raise ConfigError(
                f"CubaLIF r must be tau_mem / nir_step_s and w_in tau_syn / nir_step_s (got r = {r}, w_in = {w_in}); "
                "the graph does not follow the consumers' convention cansim writes"
            )
        n = int(np.prod([a.size for a in axes]))
        w_cin = np.asarray(cin.weight, dtype=np.float64)
        if w_cin.shape != (n, n):
            raise ConfigError(f"current_in's weight must have shape {(n, n)}, got {w_cin.shape}")
        g_in = float(w_cin[0, 0]) if n else 0.0
        if not (math.isfinite(g_in) and g_in > 0) or not np.allclose(w_cin, g_in * np.eye(n), rtol=0.0, atol=1e-12 * g_in):
            raise ConfigError("current_in's weight must be a positive multiple of the identity")
        resistance = g_in * tau_mem * tau_syn / (step * step)
        bias_in = _uniform(cin, "bias") / g_in
        v_rest = float(meta["v_rest"])
        v_leak = _uniform(cells, "v_leak")
        neurons = NeuronParams(
            model="lif",
            tau_mem_s=tau_mem,
            tau_syn_s=tau_syn,
            v_rest=v_rest,
            v_reset=_prefer(meta, "v_reset", _uniform(cells, "v_reset") + v_rest),
            v_threshold=_prefer(meta, "v_threshold", _uniform(cells, "v_threshold") + v_rest),
            resistance=_prefer(meta, "resistance", resistance),
            bias_current=_prefer(meta, "bias_current", bias_in + v_leak / resistance),  # a leak above rest is a bias
            refractory_s=float(meta["refractory_s"]),
            noise_sigma=float(meta["noise_sigma"]),
            poisson_gain_hz=float(meta["poisson_gain_hz"]),
        )
        params, pop = _population(meta, axes, attractor, neurons, dt_s, seed, backend)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise _metadata_error(exc, "metadata['cansim'] or node parameters") from None
    try:
        w_exc = np.asarray(exc.weight, dtype=np.float64)
        w_inh = np.asarray(inh.weight, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError("excitation and inhibition weights must be arrays of numbers") from None
    if w_exc.shape != (pop.size, pop.size) or w_inh.shape != (pop.size, pop.size):
        raise ConfigError(f"excitation and inhibition weights must have shape {(pop.size, pop.size)}")
    if not (np.isfinite(w_exc).all() and np.isfinite(w_inh).all()):
        raise ConfigError("excitation and inhibition weights must be finite")
    expected = pop.kernel.dense_matrix(params.global_weight) * current_gain(neurons, step)
    # rounding of the product is bounded by the product of the magnitudes
    scale = max(
        float(np.abs(expected).max()),
        float((np.abs(w_inh) @ np.abs(w_exc)).max()),
        (params.recurrent_weight + params.global_weight) * current_gain(neurons, step),  # before cancellation
        1e-300,
    )
    if not np.allclose(w_inh @ w_exc, expected, rtol=0.0, atol=WEIGHT_RTOL * scale):
        raise ConfigError("the recurrent weights are not the kernels of metadata['cansim']; the graph was edited")
    return pop


def _population(meta: dict, axes: tuple, attractor: AttractorParams, neurons: NeuronParams, dt_s: Optional[float],
                seed: Optional[int], backend: str) -> tuple[SpikingParams, SpikingPopulation]:
    """The population a graph describes: its network parameters and the population (both formats)."""
    params = _spiking_params(meta, attractor, neurons)
    pop = SpikingPopulation(
        axes,
        params,
        dt_s=float(meta["dt_s"]) if dt_s is None else dt_s,
        seed=int(meta["seed"]) if seed is None else seed,
        backend=backend,
    )
    return params, pop


def _metadata_error(exc: Exception, what: str) -> ConfigError:
    """The typed error of a failed read of a graph's metadata or parameters (OverflowError: int(inf), float(10**400))."""
    if isinstance(exc, ConfigError):
        return exc
    if isinstance(exc, KeyError):
        return ConfigError(f"metadata['cansim'] lacks the entry {exc.args[0]!r}; re-export with cansim.spiking.to_nir")
    return ConfigError(f"malformed {what}: {exc}")


def _from_nir_v1(graph: Any, meta: dict, dt_s: Optional[float], seed: Optional[int], backend: str) -> SpikingPopulation:
    """The first format: ``input -> input_scale (Scale) -> cells (CubaLIF) <-> recurrent (Affine)``, spikes as jumps."""
    nir = _nir()
    cells = graph.nodes.get("cells")
    rec = graph.nodes.get("recurrent")
    if not isinstance(cells, nir.CubaLIF) or not isinstance(rec, nir.Affine):
        raise ConfigError("the graph needs a CubaLIF node 'cells' and an Affine node 'recurrent'")
    edges = _edge_set(graph)
    if ("cells", "recurrent") not in edges or ("recurrent", "cells") not in edges:
        raise ConfigError("the graph needs the recurrent loop cells -> recurrent -> cells")
    try:
        axes = _axes_from_meta(meta)
        attractor = _attractor_from_meta(meta)
        tau_syn = _uniform(cells, "tau_syn")
        r = _uniform(cells, "r")
        if r <= 0:
            raise ConfigError(f"CubaLIF r (resistance) must be > 0, got {r}")
        v_rest = float(meta["v_rest"])
        if not np.allclose(np.asarray(cells.w_in, dtype=np.float64), tau_syn, rtol=1e-12, atol=0.0):
            raise ConfigError("CubaLIF w_in must equal tau_syn (the first format's current-jump convention)")
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
        params, pop = _population(meta, axes, attractor, neurons, dt_s, seed, backend)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise _metadata_error(exc, "metadata['cansim']") from None
    weight = np.asarray(rec.weight, dtype=np.float64)
    if weight.shape != (pop.size, pop.size):
        raise ConfigError(f"the Affine weight must have shape {(pop.size, pop.size)}, got {weight.shape}")
    expected = pop.kernel.dense_matrix(params.global_weight)
    if not np.allclose(weight, expected, rtol=1e-9, atol=1e-12) or np.any(np.asarray(rec.bias) != 0):
        raise ConfigError("the Affine weights are not the kernels of metadata['cansim']; the graph was edited")
    return pop
