"""The parameters every SLAM model shares, declared and checked once.

:class:`SlamConfig` is the frozen dataclass base of
:class:`~cansim.models.ratslam_config.RatSLAMConfig` (3-DoF RatSLAM) and
:class:`~cansim.models.whisker_ratslam.WhiskerRatSLAMConfig` (6-DoF WhiskerRatSLAM): the
pose-cell grid's metres per cell and attractor, the local-view -> pose-cell connection
(Eq 5.8-5.9 stored location or Eq 2.17/2.18 learnt weights), the experience rule and the
relaxation of the map (Eq 2.22, Eq 2.25) and the engine (backend, dtype). A model's
config redeclares a field only to give it the model's own default (e.g. ``inject_energy``
0.15 in OpenRatSLAM, zeta = 0.3 in Ch.5), and adds its own fields (grid sizes, front end).

:meth:`SlamConfig.from_dict` is the one reader of saved configs: anything but a mapping,
an unknown field or a malformed nested part raises :class:`~cansim.errors.ConfigError`
(``"not a <Config> description ..."``); out-of-range values raise the field's own
:class:`~cansim.errors.ConfigError`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, TypeVar

from cansim.errors import ConfigError, UnknownFieldError
from cansim.params import AttractorParams
from cansim.population import MAX_CELLS
from whisker_io.validation import ConfigDataclass, checked, validate_fields

__all__ = ["SlamConfig", "MAX_POSE_CELLS"]

#: Most pose cells a model's grid may have: the engine's limit
#: (:data:`cansim.population.MAX_CELLS`); a larger grid is refused when the config is
#: made, not when memory runs out.
MAX_POSE_CELLS = MAX_CELLS

C = TypeVar("C", bound="SlamConfig")


@dataclass(frozen=True)
class SlamConfig(ConfigDataclass):
    """The fields RatSLAM and WhiskerRatSLAM share (defaults: OpenRatSLAM's; each model sets its own).

    Parameters
    ----------
    cell_size_m : float
        Metres per translational pose cell (> 0).
    attractor : AttractorParams
        Kernels and global inhibition of the pose cells (Alg 3-5, Eq 2.19 / Eq 5.10).
    lv_mode : {"stored", "learnt"}
        How views feed the pose cells: the stored location (Eq 5.8) or learnt LV->PC
        weights (Eq 2.17/2.18, ``inject_energy`` as the gain delta).
    inject_energy : float
        Energy a view injects (>= 0): zeta of Eq 5.8 in stored mode, delta of Eq 2.17 in
        learnt mode.
    active_decay, decay_restore : float
        A view's decay rise per match and fall per iteration (>= 0).
    match_distance_cells : float
        Wrapped pose-cell distance (cells, Eq 2.22) above which a new experience is made (>= 0).
    correction : float
        Relaxation rate alpha of Eq 2.25, in (0, 1].
    relax_passes : int
        Relaxation passes over all links per action.
    relax_budget : int or None
        Single-link relaxation updates per step (None: unbounded; see :mod:`maps.experience_map`).
    backend : str
        CAN backend name (numba by default).
    dtype : {"float64", "float32"}
        Pose-cell activity dtype.

    Raises
    ------
    ConfigError
        A field of the wrong type or out of range (the relaxation fields are checked by
        the model's ``map_config()``, :class:`maps.experience_map.MapConfig`).
    """

    cell_size_m: float = checked(1.0, float, above=0)
    attractor: AttractorParams = field(default_factory=AttractorParams)
    lv_mode: str = checked("stored", str, choices=("stored", "learnt"))
    inject_energy: float = checked(0.15, float, minimum=0)
    active_decay: float = checked(1.0, float, minimum=0)
    decay_restore: float = checked(0.05, float, minimum=0)
    match_distance_cells: float = checked(2.0, float, minimum=0)
    correction: float = 0.5
    relax_passes: int = 10
    relax_budget: int | None = 2_000
    backend: str = checked("numba", str)
    dtype: str = checked("float64", str, choices=("float64", "float32"))

    @staticmethod
    def _check_grid_size(**dims: int) -> None:
        """Refuse a grid of more than :data:`MAX_POSE_CELLS` cells (dims: name -> cells, with multiplicity)."""
        total = 1
        for n in dims.values():
            total *= int(n)
        if total > MAX_POSE_CELLS:
            shape = " x ".join(f"{n} ({name})" for name, n in dims.items())
            raise ConfigError(f"the pose-cell grid {shape} has {total} cells, more than {MAX_POSE_CELLS}; "
                              "use fewer cells per axis (a larger cell_size_m)")

    def __post_init__(self) -> None:
        """Check every declared field, the model's own too (:func:`validate_fields`), then the attractor's type.

        A model's ``__post_init__`` calls this first, then checks what ties its own fields together
        (a field redeclared for its default keeps the check declared here).
        """
        validate_fields(self)
        if not isinstance(self.attractor, AttractorParams):
            raise ConfigError(f"attractor must be an AttractorParams (cansim.params), got {self.attractor!r}")
        from cansim.backends import registered_backends

        if self.backend not in registered_backends():  # named when the config is made, as pose_cells is
            raise ConfigError(f"backend {self.backend!r} is not a backend here; one of {', '.join(registered_backends())} "
                              "(a backend of your own: cansim.backends.register_backend first)")

    # ---------------------------------------------------------- save / load
    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (for saved models): every field, nested configs as dicts."""
        return asdict(self)

    @classmethod
    def from_dict(cls: type[C], d: Any) -> C:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        ConfigError
            ``d`` is not a mapping, names an unknown field, or a nested part (the
            attractor, the front end) is malformed: ``"not a <Config> description ..."``;
            or a value is out of range (the field's own message).
        """
        if not isinstance(d, Mapping):
            raise ConfigError(f"not a {cls.__name__} description: expected a dict (to_dict's output), got {type(d).__name__}")
        try:
            return cls(**cls._fields_from_dict(dict(d)))
        except UnknownFieldError as exc:  # a key that names no field (of the config or a nested part): its advice kept
            raise UnknownFieldError(f"not a {cls.__name__} description: {exc}") from None
        except (KeyError, TypeError) as exc:
            raise ConfigError(f"not a {cls.__name__} description ({exc!r})") from None

    @classmethod
    def _fields_from_dict(cls, d: dict[str, Any]) -> dict[str, Any]:
        """The constructor's keywords from a :meth:`to_dict` dict (nested parts rebuilt); a model extends it."""
        if isinstance(d.get("attractor"), Mapping):
            d["attractor"] = AttractorParams(**{k: tuple(v) if isinstance(v, list) else v for k, v in d["attractor"].items()})
        return d
