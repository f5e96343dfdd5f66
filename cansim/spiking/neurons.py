"""Spiking neuron models of a spiking attractor population: LIF and Poisson.

Both models read the same synaptic current ``I`` (threshold units, resistance ``R``):

* **LIF** (leaky integrate-and-fire):
  ``tau_mem dv/dt = (v_rest - v) + R (I + i_bias)``; a spike when ``v > v_threshold``,
  then ``v = v_reset`` for the refractory period. Integrated exactly over a step ``dt``
  with the current held constant (exponential Euler), so only the precomputed factor
  ``exp(-dt / tau_mem)`` enters the per-step arithmetic.
* **Poisson**: a spike in a step with probability ``p = gain_hz * max(I + i_bias, 0) * dt``
  (rate-to-spike conversion), followed by the same refractory period.

Membrane noise (LIF) is an Ornstein-Uhlenbeck term whose stationary standard deviation
is ``noise_sigma`` threshold units; its exact one-step increment is
``noise_sigma * sqrt(1 - exp(-2 dt / tau_mem)) * xi`` with ``xi ~ N(0, 1)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cansim.errors import ConfigError, InvalidInputError
from whisker_io.validation import ConfigDataclass, checked, config_field, validate_fields

#: most steps of ``dt_s`` one refractory period may span (a 1 ms period at 1 ps steps): a smaller step
#: is a mistyped unit, and a step of ~1e-320 s would overflow the count
MAX_REFRACTORY_STEPS = 1e9

__all__ = ["NeuronParams", "analytic_lif_rate_hz", "NEURON_MODELS"]

#: the neuron models a spiking population can use
NEURON_MODELS = ("lif", "poisson")


def _positive(name: str, value: float) -> float:
    v = _finite(name, value)
    if v <= 0:
        raise ConfigError(f"{name} must be > 0, got {value!r}; time constants and gains are positive")
    return v


def _finite(name: str, value: float) -> float:
    return float(config_field(value, name, float))


@dataclass(frozen=True)
class NeuronParams(ConfigDataclass):
    """Parameters of every neuron of a spiking population (one value shared by all cells).

    Voltages and currents are in threshold units (the default threshold is 1 above rest);
    a current ``I`` moves the resting membrane to ``v_rest + resistance * I``.

    Parameters
    ----------
    model : {"lif", "poisson"}
        Leaky integrate-and-fire or Poisson rate-to-spike neurons.
    tau_mem_s : float
        Membrane time constant (s), > 0. LIF only.
    tau_syn_s : float
        Synaptic current time constant (s), > 0: ``tau_syn dI/dt = -I`` between spikes.
    v_rest, v_reset, v_threshold : float
        Resting, reset and threshold potentials; ``v_reset < v_threshold``.
    resistance : float
        Membrane resistance ``R`` (> 0): voltage per unit current.
    bias_current : float
        Constant current added to every cell's synaptic current.
    refractory_s : float
        Absolute refractory period (s), > 0; rounded to whole steps of the simulation.
    noise_sigma : float
        Stationary std of the membrane noise (threshold units), >= 0. LIF only.
    poisson_gain_hz : float
        Poisson firing rate per unit of ``I + bias_current`` (Hz). Poisson only.
    """

    model: str = "lif"
    tau_mem_s: float = checked(0.02, float)  # and > 0 (with its own message): checked in __post_init__
    tau_syn_s: float = checked(0.005, float)
    v_rest: float = checked(0.0, float)
    v_reset: float = checked(0.0, float)
    v_threshold: float = checked(1.0, float)
    resistance: float = checked(1.0, float)
    bias_current: float = checked(0.8, float)
    refractory_s: float = checked(0.002, float)
    noise_sigma: float = checked(0.2, float)
    poisson_gain_hz: float = checked(100.0, float)

    def __post_init__(self) -> None:
        validate_fields(self)  # numpy scalars -> Python numbers: float64 arithmetic, exact NIR / JSON round trips
        if self.model not in NEURON_MODELS:
            raise ConfigError(f"model must be one of {NEURON_MODELS}, got {self.model!r}")
        for name in ("tau_mem_s", "tau_syn_s", "resistance", "refractory_s", "poisson_gain_hz"):
            _positive(name, getattr(self, name))
        if self.noise_sigma < 0:
            raise ConfigError(f"noise_sigma must be >= 0, got {self.noise_sigma!r}")
        if not self.v_reset < self.v_threshold:
            raise ConfigError(
                f"v_reset ({self.v_reset}) must lie below v_threshold ({self.v_threshold}) or a neuron would fire forever"
            )

    def refractory_steps(self, dt_s: float) -> int:
        """The refractory period in whole steps of ``dt_s`` (>= 1).

        Raises
        ------
        ConfigError
            ``dt_s`` is not finite and > 0, or exceeds the refractory period (a neuron could
            then fire in consecutive steps and the clock-driven model would be meaningless).
        """
        dt = _positive("dt_s", dt_s)
        if dt > self.refractory_s * (1.0 + 1e-9):
            raise ConfigError(
                f"dt_s = {dt} s is larger than the refractory period {self.refractory_s} s; "
                "use a smaller step or a longer refractory period"
            )
        steps = self.refractory_s / dt
        if not steps <= MAX_REFRACTORY_STEPS:  # a tiny dt: the count overflows, or the run never ends
            raise ConfigError(
                f"dt_s = {dt!r} s gives {steps:g} steps per refractory period (more than {MAX_REFRACTORY_STEPS:g}); "
                "use a larger step"
            )
        return max(1, int(round(steps)))


def analytic_lif_rate_hz(params: NeuronParams, current: float) -> float:
    """Firing rate of a noise-free LIF neuron under a constant current (continuous time).

    ``rate = 1 / (t_ref + tau_mem * ln((v_inf - v_reset) / (v_inf - v_threshold)))`` with
    ``v_inf = v_rest + R * (current + bias_current)``; 0 when ``v_inf <= v_threshold``.

    Parameters
    ----------
    params : NeuronParams
    current : float
        Constant synaptic current (threshold units).

    Returns
    -------
    float
        Rate in Hz.
    """
    c = float(current)
    if not math.isfinite(c):
        raise InvalidInputError(f"current must be finite, got {current!r}")
    v_inf = params.v_rest + params.resistance * (c + params.bias_current)
    if v_inf <= params.v_threshold:
        return 0.0
    isi = params.tau_mem_s * math.log((v_inf - params.v_reset) / (v_inf - params.v_threshold))
    return 1.0 / (params.refractory_s + isi)
