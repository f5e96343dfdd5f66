"""Run a NIR graph in an independent toolchain: snnTorch, Norse or Rockpool.

Each runner imports the graph through the toolchain's own public NIR reader, unmodified
(a deep copy is handed over, since snnTorch's reader edits the graph it is given), and
steps the resulting torch module one step at a time:

* ``"snntorch"``: ``snntorch.import_nir.import_from_nir(graph)`` (its step is 1e-4 s);
* ``"norse"``: ``norse.torch.from_nir(graph, dt=dt_s)``;
* ``"rockpool"``: ``rockpool.nn.modules.torch.nir.from_nir(graph)`` (its step is
  ``tau_mem / (1 + r)``, 0.5 % below 1e-4 s for the graphs cansim writes).

These toolchains come with the optional extra ``nir-consumers``
(``pip install 'cansim[nir-consumers]'``); :func:`consumer_status` says which can run.

**Precision.** The toolchains compute in float32 by default (``precision="float32"``).
A spiking attractor is chaotic: two runs that differ in the last bit of a membrane
potential drift apart after a few seconds (measured: the path-integrating ring driven by
Sargolini's rat, Norse in float32 against cansim's Euler simulation in float64, the
decoded headings > 1 deg apart after 2.7 s and 6 deg after 10 s). ``precision="float64"``
converts the imported module to float64 (``module.double()``; snnTorch's neurons emit their
0/1 spikes as float32, exact in any precision, so its linear layers cast their input to
their weights' precision). That widens the constants the reader wrote but cannot restore
digits it rounded away:

* snnTorch's ``import_from_nir`` hands its modules to ``nirtorch.nir_to_torch`` without
  that function's ``dtype`` argument, whose default (float32) rounds every weight and neuron
  constant, among them the decays ``alpha = 1 - dt/tau_syn`` (0.98 -> 0.98000002) and
  ``beta = 1 - dt/tau_mem`` (0.995 -> 0.99500000477): ``1 - alpha`` and ``1 - beta`` come
  out 9.5e-7 (relative) short, i.e. time constants 1e-6 longer than the graph's. With
  them, snnTorch's float64 run parts from cansim's Euler simulation 1.67 s into Sargolini's
  first minute (a cell at 0.99999946 in cansim fires in snnTorch); with the float32 weights
  but float64 decays it does not part within 5.1 s (potentials within 2e-7). (snnTorch's
  reader also divides the threshold by ``w_in dt / tau_syn`` when that is not 1; for the
  graphs cansim writes it is exactly 1.0, ``50 * (1e-4 / 0.005)``, so nothing is rescaled.)
  For ``precision="float64"`` the runner calls the reader unmodified with
  ``nirtorch.nir_to_torch`` given ``dtype=torch.float64`` and torch's default dtype float64
  for the duration of the call (:func:`_snntorch_reads_float64`; a warning is logged if a
  layer then lacks the graph's weights). The module then holds the graph's values bit for
  bit and runs the arithmetic of ``NIRGraphSimulator(graph, integration="euler")`` up to
  rounding (cansim computes ``i <- a i + ((1 - a) w_in) x``, whose ``(1 - a) w_in`` is
  1.0000000000000009; snnTorch ``i <- alpha i + x``): no spike
  differs from cansim's over the first 5.1 s of Sargolini (potentials within 2.2e-14), and
  over its whole first minute the decoded headings stay within 0.32 deg of cansim's (RMS
  error 21.280 against 21.281 deg; before, the run parted at 1.67 s), as over the held-out
  minute 300-360 s (27.240 against 27.241 deg, at most 0.32 deg apart).
* Norse's reader turns every array into a tensor with its ``_to_tensor``, which calls
  ``.float()``: the linear layers' weights are rounded to float32 (``1e-4 ->
  9.99999975e-5``; its neuron constants, ``1/tau`` = 200 and 50 s^-1, ``w_in``, ``r`` and
  the threshold, are exact either way). With them, Norse's float64 run parted from
  cansim's Euler simulation 32 s into a held-out minute of Sargolini (300-360 s; RMS
  heading error 32.7 against 27.2 deg). For ``precision="float64"`` the runner calls the
  reader unmodified with that function keeping float64 for the duration of the call
  (:func:`_norse_reads_float64`); the module then holds the graph's weights bit for bit
  and over the held-out minute the headings stay within 0.32 deg of cansim's (RMS 27.240
  against 27.241 deg).
* Rockpool's module does not run in float64 (its state stays float32), so it is refused.

Measured with ``python examples/nir_ring_rat_heading.py --cells 120 --seconds 60 --trace
[--start-s 300]`` run as ``--who cansim --integration euler`` and as ``--who snntorch|norse
--precision float64``, the two ``--out`` files' ``decoded_heading_rad`` (every 20 ms) compared.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import importlib
import io
import logging
import math
from typing import Any, Callable

import numpy as np

from cansim.errors import ConfigError, InvalidInputError, MissingExtraError, ShapeError, missing_extra

__all__ = ["NIR_CONSUMERS", "PRECISIONS", "consumer_status", "ConsumerRunner"]

log = logging.getLogger(__name__)

#: the arithmetic a consumer's module can run in (:class:`ConsumerRunner`'s ``precision``)
PRECISIONS = ("float32", "float64")

#: the toolchains a graph can be run in, and the module each needs
NIR_CONSUMERS = {"snntorch": "snntorch.import_nir", "norse": "norse.torch", "rockpool": "rockpool.nn.modules.torch.nir"}


def _to_weight_dtype(layer: Any, args: tuple) -> tuple:
    """Forward pre-hook: a linear layer's inputs in its weights' precision (spikes are 0/1: exact either way)."""
    return tuple(a.to(layer.weight.dtype) if hasattr(a, "to") else a for a in args)


@contextlib.contextmanager
def _snntorch_reads_float64(torch: Any) -> Any:
    """While open, snnTorch's reader builds its module in float64 (module docstring, *Precision*).

    snnTorch's ``import_from_nir`` hands its modules to ``nirtorch.nir_to_torch`` without
    that function's ``dtype`` argument, whose default (``torch.float32``) casts every weight
    and every neuron constant to float32. Here that function takes ``dtype=torch.float64``
    and torch's default dtype is float64 (snnTorch builds its tensors with ``torch.Tensor``),
    so the constants keep the graph's float64 values; both are restored on exit.
    """
    import nirtorch

    reader, default = nirtorch.nir_to_torch, torch.get_default_dtype()
    nirtorch.nir_to_torch = functools.partial(reader, dtype=torch.float64)
    torch.set_default_dtype(torch.float64)
    try:
        yield
    finally:
        nirtorch.nir_to_torch = reader
        torch.set_default_dtype(default)


@contextlib.contextmanager
def _norse_reads_float64(torch: Any) -> Any:
    """While open, Norse's reader builds its module in float64 (module docstring, *Precision*).

    Norse's ``from_nir`` turns every array of the graph into a tensor with its module's
    ``_to_tensor``, which calls ``.float()`` (numbers: ``dtype=torch.float32``): the
    linear layers' weights are rounded to float32 (``1e-4 -> 9.99999975e-5``). Here that
    function keeps float64 instead; it is restored on exit. The reader itself runs as
    written.
    """
    from norse.torch.utils import import_nir

    def to_float64(tensor: Any) -> Any:
        if isinstance(tensor, torch.Tensor):
            return tensor
        return torch.as_tensor(np.asarray(tensor, dtype=np.float64), dtype=torch.float64)

    reader = import_nir._to_tensor
    import_nir._to_tensor = to_float64
    try:
        yield
    finally:
        import_nir._to_tensor = reader


#: how each consumer's reader is made to keep the graph's float64 numbers (``precision="float64"``)
_FLOAT64_READERS = {"snntorch": _snntorch_reads_float64, "norse": _norse_reads_float64}


def consumer_status() -> dict[str, tuple[bool, str]]:
    """``{name: (usable, reason)}`` for every consumer in :data:`NIR_CONSUMERS` (imports each once)."""
    out = {}
    for name, module in NIR_CONSUMERS.items():
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                importlib.import_module(module)
        except Exception as exc:  # noqa: BLE001 - any import failure means "not usable", with its reason
            out[name] = (False, f"cannot import {module}: {type(exc).__name__}: {exc}; pip install 'cansim[nir-consumers]'")
        else:
            out[name] = (True, f"{module} imports")
    return out


class ConsumerRunner:
    """A NIR graph imported into one consumer, stepped one step at a time.

    Parameters
    ----------
    graph : nir.NIRGraph
        Handed to the consumer's reader as written (a deep copy).
    consumer : {"snntorch", "norse", "rockpool"}
    dt_s : float
        The step for Norse (the others fix their own; see the module docstring).
    precision : {"float32", "float64"}
        The module's arithmetic (module docstring, *Precision*; float64 for snnTorch and Norse).

    Raises
    ------
    ConfigError
        An unknown consumer, one that cannot be imported here, or a bad step.
    """

    def __init__(self, graph: Any, consumer: str, *, dt_s: float = 1e-4, precision: str = "float32") -> None:
        if consumer not in NIR_CONSUMERS:
            raise ConfigError(f"consumer must be one of {sorted(NIR_CONSUMERS)}, got {consumer!r}")
        if precision not in PRECISIONS:
            raise ConfigError(f"precision must be one of {list(PRECISIONS)}, got {precision!r}")
        if precision == "float64" and consumer == "rockpool":
            raise ConfigError("rockpool's module runs in float32 only (its state stays float32); use precision='float32'")
        if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and dt_s > 0):
            raise ConfigError(f"dt_s must be finite and > 0, got {dt_s!r}")
        try:
            import torch
        except ImportError as exc:
            raise missing_extra("running NIR consumers", "torch", "nir-consumers") from exc
        self._torch = torch
        self.consumer = consumer
        g = copy.deepcopy(graph)
        sink = io.StringIO()  # snnTorch's reader prints its progress and rescaling notes
        try:
            with contextlib.redirect_stdout(sink), torch.no_grad():
                mod = importlib.import_module(NIR_CONSUMERS[consumer])
                wide = _FLOAT64_READERS[consumer](torch) if precision == "float64" else contextlib.nullcontext()
                with wide:
                    if consumer == "snntorch":
                        self._module = mod.import_from_nir(g)
                    elif consumer == "norse":
                        self._module = mod.from_nir(g, dt=float(dt_s))
                    else:
                        self._module = mod.from_nir(g)
        except ImportError as exc:
            raise MissingExtraError(f"{consumer} cannot be imported: {exc}; pip install \"cansim[nir-consumers]\"") from exc
        if sink.getvalue():
            log.debug("%s reader said: %s", consumer, sink.getvalue().strip())
        self.precision = precision
        self._dtype = torch.float64 if precision == "float64" else torch.float32
        if precision == "float64":
            self._module = self._module.double()
            for name, layer in self._module.named_modules():  # 0/1 spikes emitted as float32 meet float64 weights
                if isinstance(layer, torch.nn.Linear):
                    layer.register_forward_pre_hook(_to_weight_dtype)
                    node = graph.nodes.get(name)
                    if node is not None and not np.array_equal(layer.weight.detach().cpu().numpy(), np.asarray(node.weight)):
                        log.warning("%s's layer %r does not hold the graph's float64 weights (a reader that no longer "
                                    "builds them as it did when cansim was written?): its run will part from cansim's",
                                    consumer, name)
        self._reshape: Callable[[Any], Any] = (lambda t: t[None, None]) if consumer == "rockpool" else (lambda t: t[None])
        self._n_in = self._input_size(graph)
        self._state = None

    @staticmethod
    def _input_size(graph: Any) -> int:
        import nir

        for node in graph.nodes.values():
            if isinstance(node, nir.Input):
                return int(np.prod(np.asarray(next(iter(node.input_type.values()))).ravel()))
        raise ConfigError("the graph has no Input node")

    @property
    def input_size(self) -> int:
        """Values the graph's Input node takes per step."""
        return self._n_in

    def step(self, x) -> np.ndarray:
        """One step with input ``x`` (shape ``(input_size,)``); returns the output (spikes) as float64.

        Raises
        ------
        ShapeError, InvalidInputError
            Wrong size or non-finite input.
        """
        u = np.asarray(x, dtype=np.float64).reshape(-1)
        if u.size != self._n_in:
            raise ShapeError(f"the input must have {self._n_in} values, got {u.size}")
        if not np.isfinite(u).all():
            raise InvalidInputError("the input must be finite (no NaN/inf)")
        t = self._reshape(self._torch.from_numpy(u).to(self._dtype))
        with self._torch.no_grad():
            out, self._state = self._module(t, self._state)
        return np.asarray(out.detach().cpu().numpy(), dtype=np.float64).reshape(-1)
