"""cansim's own simulation of a NIR graph written in the consumers' convention.

:class:`NIRGraphSimulator` runs graphs of ``Input``, ``Affine``, ``Linear``, ``CubaLIF`` and
``Output`` nodes - what :func:`cansim.spiking.to_nir` and
:func:`cansim.spiking.rotation_ring.rotation_ring_graph` write - with cansim's LIF
arithmetic, so that what snnTorch, Norse and Rockpool do with a graph can be compared
with what cansim does with the same graph (``tests/test_nir_consumers.py``).

Semantics (the convention of :mod:`cansim.spiking.nir_io`): the graph is stepped with a
fixed step ``dt``; a CubaLIF node's output is 1 in a step with a spike and 0 otherwise,
held for the step; the inputs of a node are summed. One step, in order:

1. every Linear / Affine node maps the sum of its sources: the graph's input of this
   step, other Linear / Affine nodes of this step, or the CubaLIF spikes of the previous
   step (one step of synaptic delay on every path from a neuron to a neuron);
2. every CubaLIF node integrates ``tau_syn dI/dt = -I + w_in x`` and
   ``tau_mem dv/dt = (v_leak - v) + r I`` exactly over the step with ``x`` and then ``I``
   held (``I <- a_syn I + (1 - a_syn) w_in x``, ``v <- v_inf + (v - v_inf) a_mem``,
   ``v_inf = v_leak + r I``: the exponential Euler of :mod:`cansim.spiking.neurons`); a
   spike when ``v > v_threshold``, then ``v = v_reset`` and the cell is held there for
   ``refractory_steps`` steps (0: none, as in the consumers; 1: as cansim's population
   with a refractory period of one step);
3. the Output node returns the sum of its sources (spikes of this step).

The consumers use Euler's method instead (``1 - dt/tau`` for ``exp(-dt/tau)``); at
``dt = 0.1 ms`` and ``tau_syn = 5 ms`` the two differ by 1e-4 per step.
``integration="euler"`` runs that arithmetic: on the 0.8-s turning protocol of
``tests/test_nir_consumers.py`` the ring then turns by exactly snnTorch's angle (67.345 deg
both, against 70.39 deg with the exponential Euler), so the consumers' differences from
cansim's default simulation are the discretisation, not the graph. Over a minute the
runs still part (the bump's position is neutral, and a spike decided differently by float32
rounding moves it for good): on 60 s of a rat's turning (``examples/nir_ring_rat_heading.py``)
cansim with ``"euler"`` errs 21.3 deg RMS, Norse 21.5 and snnTorch 7.3.
"""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from cansim.errors import ConfigError, InvalidInputError, ShapeError

__all__ = ["NIRGraphSimulator"]


def _nir():
    from cansim.spiking.nir_io import _nir as load

    return load()


def _array(node: Any, name: str, size: Optional[int] = None) -> np.ndarray:
    try:
        arr = np.asarray(getattr(node, name), dtype=np.float64)
    except (TypeError, ValueError, AttributeError):
        raise ConfigError(f"NIR node parameter {name!r} must be an array of numbers") from None
    if not np.isfinite(arr).all():
        raise ConfigError(f"NIR node parameter {name!r} must be finite")
    if size is not None:
        arr = arr.reshape(-1)
        if arr.size == 1:
            arr = np.full(size, float(arr[0]))
        if arr.size != size:
            raise ConfigError(f"NIR node parameter {name!r} has {arr.size} entries, expected {size}")
    return arr


class NIRGraphSimulator:
    """Clock-driven simulation of a NIR graph of LIF cells and linear maps (see the module docstring).

    Parameters
    ----------
    graph : nir.NIRGraph
        One ``Input`` and one ``Output`` node; ``Affine``, ``Linear`` and ``CubaLIF`` nodes.
    dt_s : float, optional
        The step (s); default ``graph.metadata["cansim"]["nir_step_s"]`` or 1e-4 s.
    refractory_steps : int
        Steps a cell is held at ``v_reset`` after a spike (0: none, as the consumers).
    integration : {"exact", "euler"}
        ``"exact"``: the exponential Euler of the module docstring (cansim's populations'
        arithmetic); ``"euler"``: the consumers' forward Euler, ``exp(-dt/tau)`` replaced by
        ``1 - dt/tau`` in both updates (snnTorch's ``Synaptic`` and Norse's ``CubaLIF`` as
        they import these graphs: current first, then the potential from the new current).

    Raises
    ------
    ConfigError
        A node type other than those, not exactly one Input and one Output node, an edge
        to or from an unknown node, a loop of linear maps with no neuron in it, mismatched
        sizes, non-finite or non-positive parameters.
    """

    def __init__(self, graph: Any, *, dt_s: Optional[float] = None, refractory_steps: int = 0,
                 integration: str = "exact") -> None:
        nir = _nir()
        if not isinstance(graph, nir.NIRGraph):
            raise ConfigError("NIRGraphSimulator needs a nir.NIRGraph (e.g. from nir.read)")
        if dt_s is None:
            meta = (graph.metadata or {}).get("cansim") if isinstance(graph.metadata, dict) else None
            dt_s = meta.get("nir_step_s", 1e-4) if isinstance(meta, dict) else 1e-4
        try:
            dt = float(dt_s)
        except (TypeError, ValueError):
            raise ConfigError(f"dt_s must be a number of seconds, got {dt_s!r}") from None
        if not (math.isfinite(dt) and dt > 0):
            raise ConfigError(f"dt_s must be finite and > 0, got {dt_s!r}")
        if isinstance(refractory_steps, bool) or not isinstance(refractory_steps, (int, np.integer)) or refractory_steps < 0:
            raise ConfigError(f"refractory_steps must be an integer >= 0, got {refractory_steps!r}")
        if integration not in ("exact", "euler"):
            raise ConfigError(f"integration must be 'exact' or 'euler', got {integration!r}")
        self._dt = dt
        self._n_ref = int(refractory_steps)
        self.integration = integration
        nodes = dict(graph.nodes)
        inputs = [k for k, v in nodes.items() if isinstance(v, nir.Input)]
        outputs = [k for k, v in nodes.items() if isinstance(v, nir.Output)]
        if len(inputs) != 1 or len(outputs) != 1:
            raise ConfigError(f"the graph needs exactly one Input and one Output node, got {len(inputs)} and {len(outputs)}")
        self._input, self._output = inputs[0], outputs[0]
        self._linear: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._cells: dict[str, dict[str, np.ndarray]] = {}
        for name, node in nodes.items():
            if isinstance(node, (nir.Input, nir.Output)):
                continue
            if isinstance(node, (nir.Affine, nir.Linear)):
                w = _array(node, "weight")
                if w.ndim != 2 or w.size == 0:
                    raise ConfigError(f"node {name!r}: the weight must be a non-empty 2-D matrix, got shape {w.shape}")
                b = _array(node, "bias", w.shape[0]) if isinstance(node, nir.Affine) else np.zeros(w.shape[0])
                self._linear[name] = (w, b)
            elif isinstance(node, nir.CubaLIF):
                n = int(np.asarray(node.tau_mem).size)
                if n == 0:
                    raise ConfigError(f"node {name!r} has no cells")
                p = {k: _array(node, k, n) for k in ("tau_syn", "tau_mem", "r", "v_leak", "v_threshold", "v_reset", "w_in")}
                if np.any(p["tau_syn"] <= 0) or np.any(p["tau_mem"] <= 0):
                    raise ConfigError(f"node {name!r}: tau_syn and tau_mem must be > 0")
                if np.any(p["v_reset"] >= p["v_threshold"]):
                    raise ConfigError(f"node {name!r}: v_reset must lie below v_threshold or a cell would fire forever")
                if integration == "exact":
                    p["a_syn"] = np.exp(-dt / p["tau_syn"])
                    p["a_mem"] = np.exp(-dt / p["tau_mem"])
                else:
                    p["a_syn"] = 1.0 - dt / p["tau_syn"]
                    p["a_mem"] = 1.0 - dt / p["tau_mem"]
                self._cells[name] = p
            else:
                raise ConfigError(
                    f"node {name!r} is a {type(node).__name__}; this simulator runs Input, Output, Affine, Linear and CubaLIF nodes"
                )
        try:
            edges = [(str(a), str(b)) for a, b in graph.edges]
        except (TypeError, ValueError):
            raise ConfigError("the graph's edges must be (source, target) pairs") from None
        self._sources: dict[str, list[str]] = {k: [] for k in nodes}
        for a, b in edges:
            if a not in nodes or b not in nodes:
                raise ConfigError(f"the edge {a} -> {b} names a node the graph does not have")
            if b == self._input or a == self._output:
                raise ConfigError(f"the edge {a} -> {b} leads into the Input or out of the Output node")
            self._sources[b].append(a)
        self._sizes: dict[str, int] = {}
        in_type = getattr(nodes[self._input], "input_type", {}) or {}
        try:
            self._n_in = int(np.prod(np.asarray(next(iter(in_type.values()))).ravel()))
        except (StopIteration, TypeError, ValueError):
            raise ConfigError("the Input node needs an input_type with its size") from None
        self._sizes[self._input] = self._n_in
        for name, (w, _) in self._linear.items():
            self._sizes[name] = w.shape[0]
        for name, p in self._cells.items():
            self._sizes[name] = p["tau_mem"].size
        self._order = self._linear_order()
        for name in list(self._linear) + list(self._cells) + [self._output]:
            expect = self._linear[name][0].shape[1] if name in self._linear else self._sizes.get(name)
            for src in self._sources[name]:
                if expect is not None and self._sizes[src] != expect:
                    raise ConfigError(f"the edge {src} -> {name} carries {self._sizes[src]} values, {name} takes {expect}")
                expect = self._sizes[src] if expect is None else expect
            if name == self._output:
                if not self._sources[name]:
                    raise ConfigError("nothing feeds the Output node")
                self._sizes[name] = expect
        self.reset()

    def _linear_order(self) -> list[str]:
        """Linear nodes in an order where same-step sources come first; a linear-only loop is an error."""
        order: list[str] = []
        state: dict[str, int] = {}

        def visit(name: str, path: tuple[str, ...]) -> None:
            if state.get(name) == 2:
                return
            if state.get(name) == 1:
                raise ConfigError(f"the linear maps {' -> '.join(path + (name,))} form a loop with no neuron in it")
            state[name] = 1
            for src in self._sources[name]:
                if src in self._linear:
                    visit(src, path + (name,))
            state[name] = 2
            order.append(name)

        for name in self._linear:
            visit(name, ())
        return order

    # ------------------------------------------------------------ properties
    @property
    def dt_s(self) -> float:
        """The step (s)."""
        return self._dt

    @property
    def input_size(self) -> int:
        """Values the Input node takes per step."""
        return self._n_in

    @property
    def output_size(self) -> int:
        """Values the Output node gives per step."""
        return self._sizes[self._output]

    @property
    def neuron_nodes(self) -> tuple[str, ...]:
        """Names of the CubaLIF nodes."""
        return tuple(self._cells)

    def spikes(self, node: str) -> np.ndarray:
        """The 0/1 spikes of CubaLIF node ``node`` in the last step (a copy)."""
        if node not in self._cells:
            raise ConfigError(f"{node!r} is not a CubaLIF node of the graph; they are {list(self._cells)}")
        return self._z[node].copy()

    def reset(self) -> None:
        """Every cell at its leak potential with no current, no spikes, time 0."""
        self._i = {k: np.zeros(p["tau_mem"].size) for k, p in self._cells.items()}
        self._v = {k: p["v_leak"].copy() for k, p in self._cells.items()}
        self._ref = {k: np.zeros(p["tau_mem"].size, dtype=np.int64) for k, p in self._cells.items()}
        self._z = {k: np.zeros(p["tau_mem"].size) for k, p in self._cells.items()}

    def step(self, x) -> np.ndarray:
        """Advance one step with input ``x`` (shape ``(input_size,)``); returns the Output's values.

        Raises
        ------
        ShapeError, InvalidInputError
            ``x`` has the wrong size or is not finite; the state is unchanged.
        """
        u = np.asarray(x, dtype=np.float64).reshape(-1) if np.ndim(x) else np.full(self._n_in, float(x))
        if u.size != self._n_in:
            raise ShapeError(f"the input must have {self._n_in} values, got {u.size}")
        if not np.isfinite(u).all():
            raise InvalidInputError("the input must be finite (no NaN/inf)")
        value: dict[str, np.ndarray] = {self._input: u}
        value.update(self._z)  # previous step's spikes: one step of delay from neuron to neuron
        for name in self._order:
            w, b = self._linear[name]
            src = self._sources[name]
            total = sum(value[s] for s in src) if src else np.zeros(w.shape[1])
            nz = np.flatnonzero(total)
            if 4 * nz.size < total.size:  # spikes are sparse: only the columns that carry something
                value[name] = w[:, nz] @ total[nz] + b
            else:
                value[name] = w @ total + b
        new_z = {}
        for name, p in self._cells.items():
            src = self._sources[name]
            x_in = sum(value[s] for s in src) if src else 0.0
            i = p["a_syn"] * self._i[name] + (1.0 - p["a_syn"]) * p["w_in"] * x_in
            v_inf = p["v_leak"] + p["r"] * i
            v = v_inf + (self._v[name] - v_inf) * p["a_mem"]
            ref = self._ref[name]
            held = ref > 0
            fire = ~held & (v > p["v_threshold"])
            v = np.where(fire | held, p["v_reset"], v)
            self._ref[name] = np.where(held, ref - 1, np.where(fire, self._n_ref, 0))
            self._i[name], self._v[name] = i, v
            new_z[name] = fire.astype(np.float64)
        self._z = new_z
        value.update(new_z)
        return sum(value[s] for s in self._sources[self._output])

    def run(self, inputs) -> np.ndarray:
        """:meth:`step` over the rows of ``inputs`` (shape ``(n_steps, input_size)``); returns ``(n_steps, output_size)``."""
        arr = np.asarray(inputs, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != self._n_in:
            raise ShapeError(f"inputs must have shape (n_steps, {self._n_in}), got {arr.shape}")
        return np.stack([self.step(row) for row in arr]) if len(arr) else np.zeros((0, self.output_size))
