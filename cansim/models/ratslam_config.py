"""RatSLAM's parameters: one name per concept, shared with WhiskerRatSLAM.

:class:`RatSLAMConfig` holds the 3-DoF model's parameters under the names the rest of
cansim uses (``cell_size_m``, ``attractor``, ``inject_energy``,
``match_distance_cells``, ``relax_passes``, ``frontend``...) and builds the parts'
own parameters from them: :class:`cansim.params.AttractorParams` (a field),
:class:`cansim.local_view.LocalViewParams`, :class:`maps.experience_map.MapConfig`
and :class:`maps.se2.SE2Geometry`.

OpenRatSLAM's ``config_*.txt.in`` files are read by :meth:`RatSLAMConfig.from_file`,
which delegates to the adapter :mod:`cansim.models.openratslam_config`; that module holds
the one table from OpenRatSLAM's flat key names to these fields. Passing an
OpenRatSLAM name as a keyword raises :class:`~cansim.errors.ConfigError` naming the
field to use.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, fields
from typing import Any, Union

from cansim.errors import ConfigError, UnknownFieldError
from cansim.frontends.tactile import TactileTemplateConfig
from cansim.frontends.visual import VisualTemplateConfig
from cansim.local_view import LocalViewParams
from cansim.models.openratslam_config import (
    OPENRATSLAM_KEYS,
    config_from_flat_dict,
    read_openratslam_file,
    read_openratslam_text,
    renamed,
)
from cansim.models.slam_config import SlamConfig
from cansim.params import AttractorParams
from maps.experience_map import MapConfig
from maps.se2 import SE2Geometry
from whisker_io.validation import checked, config_field

__all__ = ["RatSLAMConfig", "FrontEndConfig"]

FrontEndConfig = Union[str, VisualTemplateConfig, TactileTemplateConfig]
"""What :attr:`RatSLAMConfig.frontend` holds: ``"ids"`` or a front-end config."""

_FRONTEND_KINDS: dict[str, type] = {"visual": VisualTemplateConfig, "tactile": TactileTemplateConfig}


def _per_axis(value: Any) -> tuple[Any, ...]:
    return tuple(value) if isinstance(value, (list, tuple)) else (value,)


@dataclass(frozen=True)
class RatSLAMConfig(SlamConfig):
    """All RatSLAM parameters (defaults: OpenRatSLAM's).

    The fields shared with WhiskerRatSLAM (``cell_size_m``, ``attractor``, ``lv_mode``,
    ``inject_energy``, ``active_decay``, ``decay_restore``, ``match_distance_cells``,
    ``correction``, ``relax_passes``, ``relax_budget``, ``backend``, ``dtype``) are
    declared and checked once, in :class:`cansim.models.slam_config.SlamConfig`.

    OpenRatSLAM's key for a field is given in brackets, for translating its config
    files by hand (:meth:`from_file` does it; see :mod:`cansim.models.openratslam_config`).

    Parameters
    ----------
    xy_cells : int
        Pose cells on each of the x and y axes (21) [``pc_dim_xy``].
    heading_cells : int
        Pose cells on the heading axis (36, 10 deg each) [``pc_dim_th``].
    cell_size_m : float
        Metres per translational pose cell (1.0; thesis Table 3.1: 0.015) [``pc_cell_x_size``].
    attractor : AttractorParams
        Kernels and global inhibition (Alg 3-5): OpenRatSLAM's 7-tap sigma-1
        excitation, 5-tap sigma-2 inhibition, phi 2e-5. Widths odd, sigmas > 0 cells
        [``pc_w_e_dim``, ``pc_w_e_var``, ``pc_w_i_dim``, ``pc_w_i_var``, ``pc_global_inhib``].
    decode_window : int
        Half-width (cells) of the population-vector box around the maximum (3) [``pc_cells_to_avg``].
    lv_mode : {"stored", "learnt"}
        How views feed the pose cells: OpenRatSLAM's stored location (Eq 5.8, default)
        or explicit learnt LV->PC weights (Eq 2.17/2.18, ``inject_energy`` as the gain).
    inject_energy : float
        Energy a view injects at its stored cell (0.15) [``pc_vt_inject_energy``].
    active_decay, decay_restore : float
        A view's decay rise per match (1.0) and fall per iteration (0.05)
        [``vt_active_decay``, ``pc_vt_restore``].
    match_distance_cells : float
        Wrapped pose-cell distance (cells, Eq 2.22) above which a new experience is
        made (2; thesis Table 3.1: 1) [``exp_delta_pc_threshold``].
    correction : float
        Relaxation rate alpha of Eq 2.25, in (0, 1] (0.5) [``exp_correction``].
    relax_passes : int
        Relaxation passes over all links per action (10) [``exp_loops``].
    relax_budget : int or None
        Single-link relaxation updates per step (2,000; None = OpenRatSLAM's
        unbounded O(links) relaxation; see :mod:`maps.experience_map`).
    initial_heading_deg : float
        Facing (deg) of the map's dead reckoning before the first experience (90;
        thesis Table 3.1: 180) [``exp_initial_em_deg``].
    link_time_since_start : bool
        OpenRatSLAM never resets its link timer, so every link's ``delta_time_s`` is
        the time since the first odometry; True reproduces that, False (default)
        stores the time since the link's source experience.
    link_update : {"first", "average"}
        A repeated traversal of a link: ``"first"`` (default, OpenRatSLAM) keeps the
        first traversal's odometry, ``"average"`` the running mean of the traversals
        (m, rad, s; :mod:`maps.link_average`).
    frontend : "ids", VisualTemplateConfig or TactileTemplateConfig
        The front end, selected by the type: ``"ids"`` (precomputed view ids,
        default), a :class:`~cansim.frontends.visual.VisualTemplateConfig` (camera
        images) or a :class:`~cansim.frontends.tactile.TactileTemplateConfig` (the
        3 x 6 tactile image of Ch.3, Eq 3.1).
    frame : {"standard", "openratslam"}
        Pose-cell frame (``"openratslam"``: theta index 0 moves the packet along +y).
    dtype : {"float64", "float32"}
    backend : str
        CAN backend name (numba by default).
    strict_translation : bool
        Raise when a step moves the packet more than one cell (False: warn once of a step
        of a quarter of the grid or more - wrong units? - and, either way, of a turn of more
        than half a circle in one step - a yaw rate in deg/s?).
    pose_cells : {"population", "openratslam", "spiking"}
        The pose-cell engine: cansim's :class:`~cansim.population.Population` (any
        backend and dtype), :class:`~cansim.models.posecell_network.PosecellNetwork` (the
        C++ core's arithmetic bit for bit, float64, numba) or
        :class:`~cansim.models.spiking_pose_cells.SpikingPoseCells` (a spiking HD ring x
        place sheet, with ``spiking``'s parameters; ``backend`` and ``dtype`` do not apply).
    spiking : SpikingPoseCellParams or None
        The spiking pose cells' parameters (:class:`~cansim.models.spiking_pose_cells.SpikingPoseCellParams`:
        seed, step ``dt_s``, network time per iteration, weights); None (default): its defaults. Only with
        ``pose_cells="spiking"``; saved with the model.
    keep_first_accumulator : bool
        OpenRatSLAM does not reset its dead reckoning when it creates the very first
        experience, so the motion before experience 0 is counted again in the link to
        experience 1 and every later experience is placed that much further on (ten
        steps of 0.3 m with a new view each: experiences at 0.3, 0.9, 1.2, ... m).
        True (default, as the C++) keeps that; False resets it, as every later creation
        does (the object map's rule, thesis Alg 6) [:class:`maps.experience_map.MapConfig`].

    Raises
    ------
    ConfigError
        A field of the wrong type or out of range, an unknown field, or an OpenRatSLAM
        key name (the message names the field to use; :meth:`from_file` reads
        OpenRatSLAM files).
    """

    # shared fields (SlamConfig), at SlamConfig's defaults: cell_size_m, attractor, lv_mode,
    # inject_energy, active_decay, decay_restore, match_distance_cells, correction,
    # relax_passes, relax_budget, backend, dtype
    xy_cells: int = checked(21, int, minimum=1)
    heading_cells: int = checked(36, int, minimum=1)
    decode_window: int = checked(3, int, minimum=0)
    initial_heading_deg: float = checked(90.0, float)
    link_time_since_start: bool = checked(False, bool)
    link_update: str = "first"
    frontend: FrontEndConfig = "ids"
    frame: str = checked("standard", str, choices=("standard", "openratslam"))
    strict_translation: bool = checked(False, bool)
    pose_cells: str = checked("population", str, choices=("population", "openratslam", "spiking"))
    keep_first_accumulator: bool = checked(True, bool)
    spiking: Any = None  # SpikingPoseCellParams | None (imported only when given: the rate engines import nothing spiking)

    @classmethod
    def check_names(cls, names: Any) -> None:
        """Raise :class:`ConfigError` unless every name is a field (OpenRatSLAM names get the field to use)."""
        cls.refuse_arguments(0, names)  # silent when every name is known

    @classmethod
    def refuse_arguments(cls, n_positional: int, keywords: Any) -> None:
        """:meth:`ConfigDataclass.refuse_arguments <whisker_io.validation.ConfigDataclass.refuse_arguments>`, an
        OpenRatSLAM key name first answered with the field to use."""
        known = {f.name for f in fields(cls)}
        for name in keywords:
            new = None if name in known else renamed(name)
            if new is not None:
                raise UnknownFieldError(f"{name} is OpenRatSLAM's name: use {new}; RatSLAMConfig.from_file reads "
                                        "OpenRatSLAM files")
        super().refuse_arguments(n_positional, keywords)

    def __post_init__(self) -> None:
        super().__post_init__()  # the declared fields (SlamConfig's and these), the attractor's type
        self._check_grid_size(x=self.xy_cells, y=self.xy_cells, heading=self.heading_cells)
        if self.pose_cells == "spiking" and self.frame != "standard":
            raise ConfigError("pose_cells='spiking' uses frame='standard' (heading 0 along +x')")
        if self.spiking is not None:
            from cansim.models.spiking_pose_cells import SpikingPoseCellParams

            if not isinstance(self.spiking, SpikingPoseCellParams):
                raise ConfigError(f"spiking must be a SpikingPoseCellParams (cansim.models.spiking_pose_cells) or None, "
                                  f"got {type(self.spiking).__name__}")
            if self.pose_cells != "spiking":
                raise ConfigError(f"spiking parameters are for pose_cells='spiking', not {self.pose_cells!r}: "
                                  "set pose_cells='spiking' or leave spiking out")
        self._check_attractor()
        fe = self.frontend
        if not ((isinstance(fe, str) and fe == "ids") or isinstance(fe, (VisualTemplateConfig, TactileTemplateConfig))):
            raise ConfigError(
                f"frontend must be 'ids', a VisualTemplateConfig (camera images) or a TactileTemplateConfig "
                f"(Ch.3 tactile images), got {self.frontend!r}; e.g. frontend=VisualTemplateConfig(match_threshold=0.05)"
            )
        if self.lv_mode == "learnt" and self.pose_cells == "openratslam":
            raise ConfigError("lv_mode='learnt' needs pose_cells='population' (the C++ engine is the stored-location model)")
        if self.pose_cells == "openratslam" and (self.frame != "openratslam" or self.dtype != "float64"):
            raise ConfigError("pose_cells='openratslam' is the C++ engine: it needs frame='openratslam' and dtype='float64'")
        self.map_config()  # correction, relax_passes, relax_budget
        self.map_geometry()

    def _check_attractor(self) -> None:
        a = self.attractor
        if not isinstance(a, AttractorParams):
            raise ConfigError(f"attractor must be an AttractorParams (cansim.params), got {a!r}")
        for name in ("exc_width", "inh_width", "exc_sigma", "inh_sigma"):
            values = _per_axis(getattr(a, name))
            if len(values) not in (1, 3):
                raise ConfigError(f"attractor.{name} must be one value or 3 (x, y, heading), got {getattr(a, name)!r}")
            for v in values:
                if name.endswith("width"):
                    config_field(v, f"attractor.{name}", int, minimum=1, odd=True, hint="a kernel is centred on a cell")
                else:
                    config_field(v, f"attractor.{name}", float, above=0, hint="a standard deviation in cells")
        config_field(a.global_inhibition, "attractor.global_inhibition", float, minimum=0)

    # ------------------------------------------------------------- presets
    @classmethod
    def openratslam(cls, **overrides: Any) -> "RatSLAMConfig":
        """OpenRatSLAM parity: the C++ pose-cell engine and frame, unbounded relaxation, <= 1 cell per step, C++ link times."""
        params: dict[str, Any] = {
            "frame": "openratslam", "dtype": "float64", "relax_budget": None, "strict_translation": True,
            "pose_cells": "openratslam", "link_time_since_start": True,
        }
        params.update(overrides)
        return cls(**params)

    @classmethod
    def thesis_ch3(cls, **overrides: Any) -> "RatSLAMConfig":
        """Table 3.1 of the thesis (whisker-array RatSLAM) with the tactile front end.

        Table 3.1's template (6 x 3, no shift, step 1) is the tactile image itself
        (:data:`cansim.frontends.tactile.TACTILE_SHAPE`, compared without shifts). The
        two tuned values - the Eq 3.1 match threshold and the injected energy - are not
        printed in the thesis; pass them as overrides, e.g.
        ``thesis_ch3(frontend=TactileTemplateConfig(match_threshold=5.0), inject_energy=0.05)``.
        """
        params: dict[str, Any] = {
            "active_decay": 1.0, "xy_cells": 30, "cell_size_m": 0.015, "match_distance_cells": 1.0,
            "relax_passes": 10, "initial_heading_deg": 180.0, "frontend": TactileTemplateConfig(match_threshold=20.0),
        }
        params.update(overrides)
        return cls(**params)

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], **overrides: Any) -> "RatSLAMConfig":
        """Read an OpenRatSLAM ``config_*.txt.in`` file (``key=value`` lines, ``[section]`` headers).

        The keys are mapped onto the fields by :mod:`cansim.models.openratslam_config` (its
        docstring has the table); the front end is a
        :class:`~cansim.frontends.visual.VisualTemplateConfig` (OpenRatSLAM's is a
        camera). Unknown keys (ROS topics, drawing, visual odometry...) are ignored
        with a ``UserWarning``; a known key with a malformed or out-of-range value
        raises :class:`ConfigError` naming the key and its line. ``overrides`` (field
        names, e.g. ``frontend="ids"``) replace whole fields and win over the file.
        """
        return read_openratslam_file(path, cls, **overrides)

    @classmethod
    def from_text(cls, text: str, **overrides: Any) -> "RatSLAMConfig":
        """As :meth:`from_file`, from the file's text."""
        return read_openratslam_text(text, cls, **overrides)

    # ---------------------------------------------------------- save / load
    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (for saved models); the front end as ``"ids"`` or ``{"kind": ..., fields}``."""
        out = super().to_dict()
        if not isinstance(self.frontend, str):
            kind = next(k for k, t in _FRONTEND_KINDS.items() if isinstance(self.frontend, t))
            out["frontend"] = {"kind": kind, **asdict(self.frontend)}
        return out

    @classmethod
    def from_dict(cls, d: Any) -> "RatSLAMConfig":
        """Inverse of :meth:`to_dict` (:meth:`SlamConfig.from_dict`'s errors); also reads the flat
        form saved by earlier versions (:func:`cansim.models.openratslam_config.config_from_flat_dict`)."""
        if isinstance(d, dict) and any(k in OPENRATSLAM_KEYS for k in d):
            return config_from_flat_dict(d, cls)
        return super().from_dict(d)

    @classmethod
    def _fields_from_dict(cls, d: dict[str, Any]) -> dict[str, Any]:
        d = super()._fields_from_dict(d)
        if isinstance(d.get("spiking"), dict):
            from cansim.models.spiking_pose_cells import SpikingPoseCellParams

            d["spiking"] = SpikingPoseCellParams(**{k: tuple(v) if isinstance(v, list) else v for k, v in d["spiking"].items()})
        fe = d.get("frontend")
        if isinstance(fe, dict):
            fe = dict(fe)
            d["frontend"] = _FRONTEND_KINDS[fe.pop("kind")](**fe)
        return d

    # --------------------------------------------------------- sub-configs
    def map_config(self) -> MapConfig:
        """The experience map's core parameters."""
        return MapConfig(
            correction=self.correction, relax_passes=self.relax_passes, match_distance_cells=self.match_distance_cells,
            pc_shape=(self.xy_cells, self.xy_cells, self.heading_cells), offset_axes=(2,), relax_budget=self.relax_budget,
            link_time_since_start=self.link_time_since_start, keep_first_accumulator=self.keep_first_accumulator,
            link_update=self.link_update,
        )

    def map_geometry(self) -> SE2Geometry:
        """The experience map's SE(2) geometry (initial heading, panoramic theta axis)."""
        return SE2Geometry(initial_heading_deg=self.initial_heading_deg, heading_axis=2, heading_cells=self.heading_cells)

    def local_view_params(self) -> LocalViewParams:
        """The local-view cells' parameters: OpenRatSLAM's stored location, or learnt LV->PC weights (``lv_mode``)."""
        if self.lv_mode == "learnt":
            return LocalViewParams(mode="learnt", inject_energy=self.inject_energy, recent_exclusion=0)
        return LocalViewParams(
            mode="stored", inject_energy=self.inject_energy, active_decay=self.active_decay,
            decay_restore=self.decay_restore, recent_exclusion=10, cpp_unsigned_recent=True, rounding="truncate",
            cpp_cells=self.pose_cells == "openratslam",
        )
