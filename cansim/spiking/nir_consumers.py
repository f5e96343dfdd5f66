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
"""

from __future__ import annotations

import contextlib
import copy
import importlib
import io
import logging
import math
from typing import Any, Callable

import numpy as np

from cansim.errors import ConfigError, InvalidInputError, ShapeError

__all__ = ["NIR_CONSUMERS", "consumer_status", "ConsumerRunner"]

log = logging.getLogger(__name__)

#: the toolchains a graph can be run in, and the module each needs
NIR_CONSUMERS = {"snntorch": "snntorch.import_nir", "norse": "norse.torch", "rockpool": "rockpool.nn.modules.torch.nir"}


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

    Raises
    ------
    ConfigError
        An unknown consumer, one that cannot be imported here, or a bad step.
    """

    def __init__(self, graph: Any, consumer: str, *, dt_s: float = 1e-4) -> None:
        if consumer not in NIR_CONSUMERS:
            raise ConfigError(f"consumer must be one of {sorted(NIR_CONSUMERS)}, got {consumer!r}")
        if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and dt_s > 0):
            raise ConfigError(f"dt_s must be finite and > 0, got {dt_s!r}")
        try:
            import torch
        except ImportError as exc:
            raise ConfigError("running NIR consumers needs torch: pip install 'cansim[nir-consumers]'") from exc
        self._torch = torch
        self.consumer = consumer
        g = copy.deepcopy(graph)
        sink = io.StringIO()  # snnTorch's reader prints its progress and rescaling notes
        try:
            with contextlib.redirect_stdout(sink), torch.no_grad():
                mod = importlib.import_module(NIR_CONSUMERS[consumer])
                if consumer == "snntorch":
                    self._module = mod.import_from_nir(g)
                elif consumer == "norse":
                    self._module = mod.from_nir(g, dt=float(dt_s))
                else:
                    self._module = mod.from_nir(g)
        except ImportError as exc:
            raise ConfigError(f"{consumer} cannot be imported: {exc}; pip install 'cansim[nir-consumers]'") from exc
        if sink.getvalue():
            log.debug("%s reader said: %s", consumer, sink.getvalue().strip())
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
        t = self._reshape(self._torch.from_numpy(u.astype(np.float32)))
        with self._torch.no_grad():
            out, self._state = self._module(t, self._state)
        return np.asarray(out.detach().cpu().numpy(), dtype=np.float64).reshape(-1)
