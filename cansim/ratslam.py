"""RatSLAM (3-DoF): pose cells + local-view cells + a front end + an experience map (Ch.2-3 of the thesis).

One call per iteration, :meth:`RatSLAM.step`, in OpenRatSLAM's order:

1. the observation (camera image, 3 x 6 tactile image or precomputed view id)
   becomes a view template (:mod:`cansim.frontends`);
2. the local-view cells inject energy at the template's stored pose cell
   (``PosecellNetwork::on_view_template``: C++ truncation of the stored
   coordinates, no injection for the 10 most recent templates - with fewer
   than 10 every revisit injects, as C++'s unsigned arithmetic does - and the
   decay rules; :class:`cansim.local_view.LocalViewCells` in ``"stored"`` mode);
3. the pose cells run excitation, inhibition, global inhibition,
   normalisation, path integration and ``find_best`` (+-3 window)
   (``PosecellNetwork::on_odo``; :class:`cansim.population.Population`, or
   :class:`cansim.posecell_network.PosecellNetwork` in the parity preset);
4. the experience map dead-reckons the odometry and, once both an odometry and
   a view update have arrived, creates / links / re-localises experiences and
   relaxes (``get_action`` + ``ExperienceMap``, :mod:`maps.experience_map`).

Parameters carry OpenRatSLAM's names (:class:`RatSLAMConfig`, or an
OpenRatSLAM ``config_*.txt.in`` file via :meth:`RatSLAMConfig.from_file`).

Parity preset (:meth:`RatSLAMConfig.openratslam`): the C++ pose-cell engine
(:class:`cansim.posecell_network.PosecellNetwork`, the C++ arithmetic in the
C++ order, float64), the C++ frame (theta index 0 moves the packet along +y),
C++ view-cell arithmetic (raw stored coordinates, theta wrapped once,
truncation, out-of-grid cells skipped), OpenRatSLAM's unbounded relaxation and
never-reset link timer, and translation limited to one cell per step - the C++
four-weight shift is only valid up to one cell, so larger steps raise
:class:`InvalidInputError` (reduce the speed or raise ``pc_cell_x_size``).
Fed the same odometry and view ids (with panoramic ``relative_rad``) as
OpenRatSLAM's C++ core driven the way its ROS nodes drive it, every step's
decoded (x, y, theta), experience id, action and the final map (experience
poses, links) are bit-identical (``tests/data/openratslam_cpp_trace.csv``).
Remaining differences, all outside the core: OpenRatSLAM's ROS nodes drop the
first odometry message (it has no previous time stamp) while every step's
``dt`` is used here - skip your first sample to match; the C++ constructor never
initialises ``vt_delta_pc_th``, which ``get_action`` reads when a view among the 10
most recent is revisited before any view has injected - cansim starts it at 0,
what a fresh heap holds; the C++ bugs of the visual front end are listed (and
emulable) in :mod:`cansim.frontends.visual`.
With ``pose_cells="population"`` the same model runs on cansim's generic
engine (any backend, float32) and agrees to ~1e-15 cells per step until a
truncated coordinate falls the other way; that engine also reports a decoded
coordinate of exactly ``pc_dim`` as 0.
"""

from __future__ import annotations

import json
import logging
import math
import os
import warnings
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, Mapping

import numpy as np

from cansim.errors import ConfigError, InvalidInputError
from cansim.frontends.store import TemplateMatch
from cansim.frontends.tactile import TactileTemplateConfig, TactileTemplates
from cansim.frontends.visual import VisualTemplateConfig, VisualTemplates
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.params import AttractorParams
from cansim.population import Population
from cansim.posecell_network import PosecellNetwork
from whisker_io.errors import InvalidInputError as MapsInvalidInputError
from whisker_io.errors import CorruptFileError
from maps.experience_map import Action, ExperienceMap, ExperienceMapConfig

__all__ = ["RatSLAM", "RatSLAMConfig", "RatSLAMLog", "RatSLAMState"]

log = logging.getLogger(__name__)

_VISUAL_KEYS = tuple(f.name for f in fields(VisualTemplateConfig) if f.name != "emulate_uninitialised_clear")
_VT_DEFAULTS = VisualTemplateConfig()
_NO_INDEX = np.zeros(0, dtype=np.int64)
_NO_VALUES = np.zeros(0, dtype=np.float64)


@dataclass(frozen=True)
class RatSLAMConfig:
    """All RatSLAM parameters, with OpenRatSLAM's names and defaults.

    Pose cells: ``pc_dim_xy`` (21), ``pc_dim_th`` (36), ``pc_w_e_dim`` (7),
    ``pc_w_i_dim`` (5), ``pc_w_e_var`` (1, used as sigma in cells),
    ``pc_w_i_var`` (2), ``pc_global_inhib`` (2e-5), ``pc_cell_x_size`` (1.0 m
    per cell), ``pc_cells_to_avg`` (3, the find_best half window).
    Local view: ``pc_vt_inject_energy`` (0.15), ``pc_vt_restore`` (0.05),
    ``vt_active_decay`` (1.0). Experience map: ``exp_delta_pc_threshold`` (2
    cells), ``exp_correction`` (0.5), ``exp_loops`` (10), ``exp_initial_em_deg``
    (90). Visual templates: the fields of
    :class:`cansim.frontends.visual.VisualTemplateConfig` (``template_x_size``,
    ``vt_shift_match``, ``vt_match_threshold``, ...); ``vt_match_threshold`` is
    also the Eq 3.1 threshold of the tactile front end.

    Library settings (not in OpenRatSLAM): ``frontend`` - ``"ids"``
    (precomputed view ids), ``"visual"`` or ``"tactile"``; ``relax_budget`` -
    single-link relaxation updates per step (None = OpenRatSLAM's unbounded
    O(links) relaxation; see :mod:`maps.experience_map`); ``frame`` -
    ``"standard"`` or ``"openratslam"`` pose-cell frame; ``dtype`` -
    ``"float64"``/``"float32"``; ``backend`` - CAN backend name;
    ``strict_translation`` - raise when a step moves the packet more than one cell;
    ``pose_cells`` - the pose-cell engine: ``"population"`` (cansim's
    :class:`~cansim.population.Population`, any backend and dtype) or
    ``"openratslam"`` (:class:`~cansim.posecell_network.PosecellNetwork`, the C++
    core's arithmetic bit for bit, float64, numba); ``link_time_since_start`` -
    OpenRatSLAM never resets its link timer, so every link's ``delta_time_s``
    is the time since the first odometry; True reproduces that, False (default)
    stores the time since the link's source experience.
    """

    pc_dim_xy: int = 21
    pc_dim_th: int = 36
    pc_w_e_dim: int = 7
    pc_w_i_dim: int = 5
    pc_w_e_var: float = 1.0
    pc_w_i_var: float = 2.0
    pc_global_inhib: float = 2e-5
    pc_cell_x_size: float = 1.0
    pc_cells_to_avg: int = 3
    pc_vt_inject_energy: float = 0.15
    pc_vt_restore: float = 0.05
    vt_active_decay: float = 1.0
    exp_delta_pc_threshold: float = 2.0
    exp_correction: float = 0.5
    exp_loops: int = 10
    exp_initial_em_deg: float = 90.0
    template_x_size: int = _VT_DEFAULTS.template_x_size
    template_y_size: int = _VT_DEFAULTS.template_y_size
    image_crop_x_min: int = _VT_DEFAULTS.image_crop_x_min
    image_crop_x_max: int = _VT_DEFAULTS.image_crop_x_max
    image_crop_y_min: int = _VT_DEFAULTS.image_crop_y_min
    image_crop_y_max: int = _VT_DEFAULTS.image_crop_y_max
    vt_shift_match: int = _VT_DEFAULTS.vt_shift_match
    vt_step_match: int = _VT_DEFAULTS.vt_step_match
    vt_match_threshold: float = _VT_DEFAULTS.vt_match_threshold
    vt_normalisation: float = _VT_DEFAULTS.vt_normalisation
    vt_patch_normalise: int = _VT_DEFAULTS.vt_patch_normalise
    vt_min_patch_normalisation_std: float = _VT_DEFAULTS.vt_min_patch_normalisation_std
    vt_panoramic: bool = _VT_DEFAULTS.vt_panoramic
    frontend: str = "ids"
    relax_budget: int | None = 2_000
    frame: str = "standard"
    dtype: str = "float64"
    backend: str = "numba"
    strict_translation: bool = False
    pose_cells: str = "population"
    link_time_since_start: bool = False

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            kind = str(f.type)
            if kind == "int" and (isinstance(value, bool) or not isinstance(value, (int, np.integer))):
                raise ConfigError(f"{f.name} must be an integer, got {value!r}")
            if kind == "float" and (isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not math.isfinite(value)):
                raise ConfigError(f"{f.name} must be a finite number, got {value!r}")
            if kind == "bool" and not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{f.name} must be a boolean, got {value!r}")
        for name in ("pc_dim_xy", "pc_dim_th", "pc_w_e_dim", "pc_w_i_dim"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("pc_w_e_dim", "pc_w_i_dim"):
            if getattr(self, name) % 2 == 0:
                raise ConfigError(f"{name} must be odd (kernel centred on a cell), got {getattr(self, name)}")
        for name in ("pc_w_e_var", "pc_w_i_var", "pc_cell_x_size"):
            if getattr(self, name) <= 0:
                raise ConfigError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("pc_global_inhib", "pc_vt_inject_energy", "pc_vt_restore", "vt_active_decay", "exp_delta_pc_threshold", "pc_cells_to_avg"):
            if getattr(self, name) < 0:
                raise ConfigError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.frontend not in ("ids", "visual", "tactile"):
            raise ConfigError(f"frontend must be 'ids', 'visual' or 'tactile', got {self.frontend!r}")
        if self.frame not in ("standard", "openratslam"):
            raise ConfigError(f"frame must be 'standard' or 'openratslam', got {self.frame!r}")
        if self.dtype not in ("float64", "float32"):
            raise ConfigError(f"dtype must be 'float64' or 'float32', got {self.dtype!r}")
        if self.pose_cells not in ("population", "openratslam"):
            raise ConfigError(f"pose_cells must be 'population' or 'openratslam', got {self.pose_cells!r}")
        if self.pose_cells == "openratslam" and (self.frame != "openratslam" or self.dtype != "float64"):
            raise ConfigError("pose_cells='openratslam' is the C++ engine: it needs frame='openratslam' and dtype='float64'")
        try:
            self.experience_map_config()
        except MapsInvalidInputError as exc:
            raise ConfigError(str(exc)) from None
        if self.frontend == "visual":
            self.visual_config()
        if self.frontend == "tactile":
            TactileTemplateConfig(vt_match_threshold=self.vt_match_threshold)

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

        The two tuned values (``vt_match_threshold``, ``pc_vt_inject_energy``) are not
        printed in the thesis; pass them as overrides.
        """
        params: dict[str, Any] = {
            "vt_shift_match": 0, "vt_step_match": 1, "vt_active_decay": 1.0, "template_x_size": 6,
            "template_y_size": 3, "pc_dim_xy": 30, "pc_cell_x_size": 0.015, "exp_delta_pc_threshold": 1.0,
            "exp_loops": 10, "exp_initial_em_deg": 180.0, "frontend": "tactile", "vt_match_threshold": 20.0,
        }
        params.update(overrides)
        return cls(**params)

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], **overrides: Any) -> "RatSLAMConfig":
        """Read an OpenRatSLAM ``config_*.txt.in`` file (``key=value`` lines, ``[section]`` headers).

        Unknown keys (ROS topics, drawing, visual odometry...) are ignored with a
        ``UserWarning``; a known key with a malformed value raises :class:`ConfigError`
        naming the key. ``overrides`` win over the file.
        """
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
        return cls.from_text(text, **overrides)

    @classmethod
    def from_text(cls, text: str, **overrides: Any) -> "RatSLAMConfig":
        """As :meth:`from_file`, from the file's text."""
        types = {f.name: str(f.type) for f in fields(cls)}
        values: dict[str, Any] = {}
        for lineno, raw in enumerate(text.splitlines(), 1):
            line = raw.strip()
            if not line or line.startswith(("#", ";", "[")):
                continue
            if "=" not in line:
                raise ConfigError(f"line {lineno}: {line!r} is not 'key=value'")
            key, value = (s.strip() for s in line.split("=", 1))
            if key not in types:
                warnings.warn(f"OpenRatSLAM config key {key!r} (line {lineno}) is not used by cansim; ignored", UserWarning, stacklevel=3)
                continue
            values[key] = _parse_value(key, value, types[key])
        values.update(overrides)
        return cls(**values)

    # --------------------------------------------------------- sub-configs
    def visual_config(self) -> VisualTemplateConfig:
        """The visual front end's parameters."""
        return VisualTemplateConfig(**{k: getattr(self, k) for k in _VISUAL_KEYS})

    def experience_map_config(self) -> ExperienceMapConfig:
        """The experience map's parameters."""
        return ExperienceMapConfig(
            exp_correction=self.exp_correction, exp_loops=self.exp_loops, exp_initial_em_deg=self.exp_initial_em_deg,
            exp_delta_pc_threshold=self.exp_delta_pc_threshold, pc_dim_xy=self.pc_dim_xy, pc_dim_th=self.pc_dim_th,
            relax_budget=self.relax_budget, link_time_since_start=self.link_time_since_start,
        )

    def local_view_params(self) -> LocalViewParams:
        """The local-view cells' parameters (OpenRatSLAM stored-location mode)."""
        return LocalViewParams(
            mode="stored", pc_vt_inject_energy=self.pc_vt_inject_energy, vt_active_decay=self.vt_active_decay,
            pc_vt_restore=self.pc_vt_restore, recent_exclusion=10, cpp_unsigned_recent=True, rounding="truncate",
            cpp_cells=self.pose_cells == "openratslam",
        )


def _parse_value(key: str, value: str, kind: str) -> Any:
    try:
        if kind == "int":
            f = float(value)
            if not f.is_integer():
                raise ValueError
            return int(f)
        if kind == "float":
            f = float(value)
            if not math.isfinite(f):
                raise ValueError
            return f
        if kind == "bool":
            low = value.lower()
            if low in ("1", "true", "yes", "on"):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError
        if kind == "int | None":
            return None if value.lower() in ("none", "") else int(value)
        return value
    except ValueError:
        raise ConfigError(f"config key {key!r}: malformed value {value!r} (expected {kind})") from None


@dataclass(frozen=True)
class RatSLAMState:
    """What one :meth:`RatSLAM.step` produced.

    Attributes
    ----------
    iteration : int
        Number of steps done, this one included.
    best_pc : tuple of float
        Decoded packet (x, y, th) in fractional pose cells.
    exp_id : int
        Current experience (-1 before the first one).
    relocalised : bool
        The current experience switched to an existing, different one this step.
    action : Action
        The experience-map action of this step.
    map_pose : tuple of float
        Map pose (x m, y m, theta rad) of the current experience.
    template_id : int
        The view template of this step (-1 when no observation was given).
    new_template : bool
        The observation became a new template.
    """

    iteration: int
    best_pc: tuple[float, float, float]
    exp_id: int
    relocalised: bool
    action: Action
    map_pose: tuple[float, float, float]
    template_id: int
    new_template: bool


@dataclass(frozen=True)
class RatSLAMLog:
    """Per-iteration record of :meth:`RatSLAM.run`; row k is iteration k of the run.

    Attributes
    ----------
    exp_ids : ndarray (n,) int64
        Current experience (the Experience Metric's experience log).
    relocalised : ndarray (n,) bool
    best_pc : ndarray (n, 3)
        Decoded packet, fractional cells.
    template_ids : ndarray (n,) int64
        View template (-1 without observation).
    """

    exp_ids: np.ndarray
    relocalised: np.ndarray
    best_pc: np.ndarray
    template_ids: np.ndarray


class RatSLAM:
    """RatSLAM with OpenRatSLAM semantics (see the module docstring).

    Parameters
    ----------
    config : RatSLAMConfig, optional
        Parameters; keyword arguments with OpenRatSLAM names override it
        (``RatSLAM(pc_dim_xy=30, vt_match_threshold=0.05)``).

    Examples
    --------
    >>> slam = RatSLAM(pc_cell_x_size=0.1)
    >>> s = slam.step(0.05, 0.0, 1.0, 0)      # 5 cm/s for 1 s, view id 0
    >>> s.exp_id
    0
    """

    def __init__(self, config: RatSLAMConfig | None = None, **params: Any) -> None:
        cfg = config if config is not None else RatSLAMConfig()
        if params:
            unknown = set(params) - {f.name for f in fields(RatSLAMConfig)}
            if unknown:
                raise ConfigError(f"unknown RatSLAM parameter(s) {sorted(unknown)}; see RatSLAMConfig")
            cfg = replace(cfg, **params)
        self.config = cfg
        attractor = AttractorParams(
            exc_width=cfg.pc_w_e_dim, exc_sigma=cfg.pc_w_e_var, inh_width=cfg.pc_w_i_dim, inh_sigma=cfg.pc_w_i_var,
            global_inhibition=cfg.pc_global_inhib,
        )
        self.pose_cells: Population | PosecellNetwork
        if cfg.pose_cells == "openratslam":
            self.pose_cells = PosecellNetwork(
                cfg.pc_dim_xy, cfg.pc_dim_th, cfg.pc_cell_x_size, w_e_dim=cfg.pc_w_e_dim, w_i_dim=cfg.pc_w_i_dim,
                w_e_var=cfg.pc_w_e_var, w_i_var=cfg.pc_w_i_var, global_inhib=cfg.pc_global_inhib, cells_to_avg=cfg.pc_cells_to_avg,
            )
        else:
            self.pose_cells = Population.openratslam(
                cfg.pc_dim_xy, cfg.pc_dim_th, cfg.pc_cell_x_size, frame=cfg.frame, params=attractor,
                dtype=np.dtype(cfg.dtype), backend=cfg.backend, decode_window=cfg.pc_cells_to_avg,
            )
        self.local_view = LocalViewCells(self.pose_cells.shape, cfg.local_view_params())
        self.frontend: VisualTemplates | TactileTemplates | None
        if cfg.frontend == "visual":
            self.frontend = VisualTemplates(cfg.visual_config())
        elif cfg.frontend == "tactile":
            self.frontend = TactileTemplates(TactileTemplateConfig(vt_match_threshold=cfg.vt_match_threshold))
        else:
            self.frontend = None
        self._ids: dict[int, int] = {}
        self.experience_map = ExperienceMap(cfg.experience_map_config())
        self._best = self.pose_cells.decode()
        self.iteration = 0
        self._current_vt = 0
        self._prev_vt = 0
        self._vt_delta_pc_th = 0.0
        self._odo_update = False
        self._vt_update = False
        self._pending_index, self._pending_values = _NO_INDEX, _NO_VALUES

    # -------------------------------------------------------------- views
    @property
    def best_pc(self) -> tuple[float, float, float]:
        """Last decoded packet (x, y, th), fractional cells."""
        return (float(self._best[0]), float(self._best[1]), float(self._best[2]))

    @property
    def n_templates(self) -> int:
        """Number of view templates (local-view cells)."""
        return self.local_view.n_views

    # -------------------------------------------------------------- input
    def _check_odometry(self, vtrans: float, vrot: float, dt: float) -> tuple[float, float, float]:
        try:
            v, w, t = float(vtrans), float(vrot), float(dt)
        except (TypeError, ValueError):
            raise InvalidInputError(f"odometry must be real numbers, got vtrans={vtrans!r}, vrot={vrot!r}, dt={dt!r}") from None
        for name, val in (("vtrans", v), ("vrot", w), ("dt", t)):
            if not math.isfinite(val):
                raise InvalidInputError(f"odometry {name} must be finite, got {val!r}; drop or repair the sample")
        if t < 0:
            raise InvalidInputError(f"odometry dt must be >= 0 s, got {t!r}")
        if self.config.strict_translation and abs(v * t) > self.config.pc_cell_x_size * (1 + 1e-12):
            raise InvalidInputError(
                f"vtrans*dt = {v * t:g} m moves the packet {abs(v * t) / self.config.pc_cell_x_size:.3g} cells; "
                "OpenRatSLAM's path integration is valid for at most one cell per step - "
                "raise pc_cell_x_size or split the step"
            )
        return v, w, t

    def _match(self, observation: Any) -> TemplateMatch:
        """Observation -> template (validates first; only a new external view id is recorded)."""
        if self.frontend is None:
            ext, rad = self._view_id(observation)
            internal = self._ids.get(ext)
            if internal is None:
                internal = self._ids[ext] = len(self._ids)
                return TemplateMatch(internal, True, math.inf, rad)
            return TemplateMatch(internal, False, 0.0, rad)
        return self.frontend.match(observation)

    @staticmethod
    def _view_id(observation: Any) -> tuple[int, float]:
        """``frontend="ids"`` observation -> (view id, relative rad); validates."""
        rad = 0.0
        if isinstance(observation, tuple):
            if len(observation) != 2:
                raise InvalidInputError(f"a (view_id, relative_rad) observation needs 2 entries, got {len(observation)}")
            observation, rad_in = observation
            try:
                rad = float(rad_in)
            except (TypeError, ValueError):
                raise InvalidInputError(f"relative_rad must be a real number, got {rad_in!r}") from None
            if not math.isfinite(rad):
                raise InvalidInputError(f"relative_rad must be finite, got {rad!r}")
        if isinstance(observation, (bool, np.bool_)) or not isinstance(observation, (int, np.integer)):
            raise InvalidInputError(
                f"frontend='ids' takes an integer view id (or a (view_id, relative_rad) pair) as the observation, "
                f"got {type(observation).__name__}; use frontend='visual' or 'tactile' for images"
            )
        ext = int(observation)
        if ext < 0:
            raise InvalidInputError(f"view ids must be >= 0, got {ext}")
        return ext, rad

    # --------------------------------------------------------------- step
    def on_view(self, observation: Any) -> TemplateMatch:
        """A view update alone (OpenRatSLAM ``LocalViewMatch::on_image`` + ``PosecellNetwork::on_view_template``).

        The observation becomes a template; a revisited template's energy is queued
        for the pose cells and added before the dynamics of the next :meth:`on_odo`
        (exactly as the C++ adds it to the cells at once: nothing else touches the
        cells in between). :meth:`step` is ``on_view`` followed by ``on_odo``.

        Parameters
        ----------
        observation : int or ndarray
            See :meth:`step`.

        Returns
        -------
        TemplateMatch
            With the internal template id.

        Raises
        ------
        InvalidInputError, ShapeError
            A malformed observation; the model is unchanged.
        """
        match = self._match(observation)  # validates before any state changes
        vid = match.template_id
        th_off = match.relative_rad / (2.0 * math.pi) * self.config.pc_dim_th
        index, values = self.local_view.observe(vid, self._best, offset_cells=(0.0, 0.0, th_off) if th_off else None)
        if self.local_view.last_energy > 0:  # C++ sets vt_delta_pc_th whenever energy > 0, injected or not
            self._vt_delta_pc_th = th_off
        if len(index):
            self._pending_index = np.concatenate([self._pending_index, index])
            self._pending_values = np.concatenate([self._pending_values, values])
        self._prev_vt, self._current_vt = self._current_vt, vid
        self._vt_update = True
        return match

    def on_odo(self, vtrans: float, vrot: float, dt: float) -> RatSLAMState:
        """An odometry update alone (OpenRatSLAM ``on_odo`` of the pose cells and the map + ``get_action``).

        Parameters and errors as :meth:`step` (without the observation); the
        returned state has ``template_id = -1``.
        """
        v, w, t = self._check_odometry(vtrans, vrot, dt)
        injection = (self._pending_index, self._pending_values) if len(self._pending_index) else None
        self._best = self.pose_cells.step(v, w, t, injection=injection)
        self._pending_index, self._pending_values = _NO_INDEX, _NO_VALUES
        self._odo_update = True
        self.iteration += 1
        em = self.experience_map
        em.on_odo(v, w, t)
        result = None
        if self._odo_update and self._vt_update and self.local_view.n_views > 0:
            self._odo_update = self._vt_update = False
            rel_rad = self._vt_delta_pc_th * 2.0 * math.pi / self.config.pc_dim_th
            result = em.update(
                self.best_pc, self._current_vt, self._prev_vt, relative_rad=rel_rad, vt_delta_pc_th=self._vt_delta_pc_th
            )
        return RatSLAMState(
            iteration=self.iteration,
            best_pc=self.best_pc,
            exp_id=em.current_id if em.n_experiences else -1,
            relocalised=bool(result.relocalised) if result else False,
            action=result.action if result else Action.NO_ACTION,
            map_pose=em.current_pose(),
            template_id=-1,
            new_template=False,
        )

    def step(self, vtrans: float, vrot: float, dt: float, observation: Any = None) -> RatSLAMState:
        """Run one RatSLAM iteration: :meth:`on_view` (if an observation is given), then :meth:`on_odo`.

        Parameters
        ----------
        vtrans : float
            Forward speed, m/s.
        vrot : float
            Yaw rate, rad/s (counter-clockwise positive).
        dt : float
            Duration of the odometry sample, s.
        observation : int, ndarray or None
            ``frontend="ids"``: a view id (any non-negative integer; first-seen order
            numbers the templates) or a ``(view_id, relative_rad)`` pair - the
            rotation (rad) of a panoramic match, OpenRatSLAM's ``ViewTemplate``
            message; ``"visual"``: a uint8 image; ``"tactile"``: a 3 x 6
            tactile image; None: no view this step (odometry only).

        Returns
        -------
        RatSLAMState

        Raises
        ------
        InvalidInputError, ShapeError
            Bad odometry (NaN, negative dt, > 1 cell/step in strict mode) or a bad
            observation; the model is unchanged.
        """
        self._check_odometry(vtrans, vrot, dt)  # before the view changes anything
        if observation is None:
            return self.on_odo(vtrans, vrot, dt)
        match = self.on_view(observation)
        return replace(self.on_odo(vtrans, vrot, dt), template_id=match.template_id, new_template=bool(match.is_new))

    def run(
        self,
        vtrans: np.ndarray,
        vrot: np.ndarray,
        dt: float | np.ndarray,
        observations: Any,
        *,
        progress: bool = False,
    ) -> RatSLAMLog:
        """Call :meth:`step` for every row of an odometry/observation sequence.

        Parameters
        ----------
        vtrans, vrot : array (n,)
            m/s and rad/s per iteration.
        dt : float or array (n,)
            Seconds per iteration.
        observations : sequence of length n
            One observation per iteration (see :meth:`step`; None entries allowed).
        progress : bool
            Show a tqdm progress bar.

        Returns
        -------
        RatSLAMLog
        """
        n = len(vtrans)
        if len(vrot) != n or len(observations) != n:
            raise InvalidInputError(f"vtrans, vrot and observations must have the same length, got {n}, {len(vrot)}, {len(observations)}")
        dts = np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,))
        exp_ids = np.empty(n, dtype=np.int64)
        reloc = np.empty(n, dtype=bool)
        best = np.empty((n, 3))
        tids = np.empty(n, dtype=np.int64)
        rows: Any = range(n)
        if progress:
            from tqdm import tqdm

            rows = tqdm(rows, desc="RatSLAM", unit="it")
        for k in rows:
            obs = observations[k]
            if isinstance(obs, np.integer):
                obs = int(obs)
            s = self.step(float(vtrans[k]), float(vrot[k]), float(dts[k]), obs)
            exp_ids[k], reloc[k], best[k], tids[k] = s.exp_id, s.relocalised, s.best_pc, s.template_id
        return RatSLAMLog(exp_ids=exp_ids, relocalised=reloc, best_pc=best, template_ids=tids)

    # ------------------------------------------------------- save / resume
    def save(self, path: str | os.PathLike[str]) -> None:
        """Save the whole model (pose cells, views, templates, map) to an ``.npz`` file.

        Loading it with :meth:`load` and continuing gives exactly the same results
        as an uninterrupted run. No pickle: arrays plus a JSON string.
        """
        arrays: dict[str, Any] = {
            "ratslam_format": np.int64(1),
            "ratslam_config": np.array(json.dumps(asdict(self.config))),
            "pc_activity": self.pose_cells.activity,
            "pc_best": np.asarray(self._best, dtype=np.float64),
            "model_i": np.array([self.iteration, self._current_vt, self._prev_vt, int(self._odo_update), int(self._vt_update)], dtype=np.int64),
            "model_f": np.array([self._vt_delta_pc_th]),
            "ids_map": np.array(sorted(self._ids.items()), dtype=np.int64).reshape(-1, 2),
            "pending_index": self._pending_index,
            "pending_values": self._pending_values,
        }
        arrays.update({"lv_" + k: v for k, v in self.local_view.state_dict().items()})
        arrays.update(self.experience_map.to_arrays(prefix="em_"))
        if self.frontend is not None:
            arrays.update(self.frontend.to_arrays(prefix="vt_"))
        np.savez(path, **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "RatSLAM":
        """Load a model written by :meth:`save`.

        Raises
        ------
        CorruptFileError
            The file is unreadable or a field is missing or malformed (named in the error).
        """
        try:
            archive = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise CorruptFileError(f"cannot be read as an .npz archive ({exc})", path=path) from exc
        if not hasattr(archive, "files"):
            raise CorruptFileError("holds a single array, not an .npz archive", path=path)
        with archive:
            try:
                arrays = {k: archive[k] for k in archive.files}
            except Exception as exc:
                raise CorruptFileError(f"damaged archive member ({exc})", path=path) from exc
        return cls.from_arrays(arrays)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> "RatSLAM":
        """Rebuild a model from the arrays :meth:`save` writes."""

        def need(key: str) -> np.ndarray:
            if key not in arrays:
                raise CorruptFileError("missing", field=key)
            return np.asarray(arrays[key])

        try:
            cfg = RatSLAMConfig(**json.loads(str(need("ratslam_config"))))
        except (json.JSONDecodeError, TypeError, ConfigError) as exc:
            raise CorruptFileError(f"not a valid RatSLAMConfig JSON ({exc})", field="ratslam_config") from exc
        model = cls(cfg)
        act = need("pc_activity")
        if act.shape != model.pose_cells.shape or act.dtype != model.pose_cells.dtype:
            raise CorruptFileError(f"shape/dtype {act.shape}/{act.dtype}, expected {model.pose_cells.shape}/{model.pose_cells.dtype}", field="pc_activity")
        try:
            model.pose_cells.activity = act
        except InvalidInputError as exc:
            raise CorruptFileError(str(exc), field="pc_activity") from exc
        best = need("pc_best")
        mi, mf, ids = need("model_i"), need("model_f"), need("ids_map")
        if best.shape != (3,) or not np.all(np.isfinite(best)):
            raise CorruptFileError("expected 3 finite numbers", field="pc_best")
        if mi.shape != (5,) or mi.dtype.kind != "i" or mf.shape != (1,) or not np.isfinite(mf[0]):
            raise CorruptFileError("expected 5 integers (and model_f 1 finite number)", field="model_i")
        if ids.ndim != 2 or ids.shape[1] != 2 or ids.dtype.kind != "i":
            raise CorruptFileError(f"expected an (n, 2) integer array, got {ids.shape}", field="ids_map")
        lv_state = {k[3:]: v for k, v in arrays.items() if k.startswith("lv_")}
        try:
            model.local_view = LocalViewCells.from_state(lv_state, cfg.local_view_params())
        except InvalidInputError as exc:
            raise CorruptFileError(str(exc), field="lv_*") from exc
        model.experience_map = ExperienceMap.from_arrays(arrays, prefix="em_")
        if model.frontend is not None:
            try:
                model.frontend.load_arrays(dict(arrays), prefix="vt_")
            except ConfigError as exc:
                raise CorruptFileError(str(exc), field="vt_*") from exc
        model._best = np.array(best, dtype=np.float64)
        if isinstance(model.pose_cells, PosecellNetwork):
            model.pose_cells.best = model._best
        model.iteration, model._current_vt, model._prev_vt = int(mi[0]), int(mi[1]), int(mi[2])
        model._odo_update, model._vt_update = bool(mi[3]), bool(mi[4])
        model._vt_delta_pc_th = float(mf[0])
        model._ids = {int(a): int(b) for a, b in ids.tolist()}
        p_idx, p_val = need("pending_index"), need("pending_values")
        if p_idx.ndim != 1 or p_idx.shape != p_val.shape or p_idx.dtype.kind != "i" or (len(p_idx) and (p_idx.min() < 0 or p_idx.max() >= model.pose_cells.size)):
            raise CorruptFileError("expected matching 1-D index/value arrays of pose-cell indices", field="pending_index")
        model._pending_index, model._pending_values = p_idx.astype(np.int64), p_val.astype(np.float64)
        return model
