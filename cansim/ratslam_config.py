"""RatSLAM's parameters, with OpenRatSLAM's names, and the adapter for its config files.

:class:`RatSLAMConfig` is the one place where OpenRatSLAM's flat key names live: it
reads OpenRatSLAM ``config_*.txt.in`` files (:meth:`RatSLAMConfig.from_file`) and maps
the keys onto the parts' own parameters - :class:`cansim.params.AttractorParams`
(kernels, global inhibition), :class:`cansim.local_view.LocalViewParams`,
:class:`maps.experience_map.MapConfig` and :class:`maps.se2.SE2Geometry`, and the
visual / tactile front-end configs.
"""

from __future__ import annotations

import functools
import math
import os
import typing
import warnings
from dataclasses import dataclass, fields
from typing import Any, Optional

import numpy as np

from cansim.errors import ConfigError
from cansim.frontends.tactile import TactileTemplateConfig
from cansim.frontends.visual import VisualTemplateConfig
from cansim.local_view import LocalViewParams
from cansim.params import AttractorParams
from maps.experience_map import MapConfig
from maps.se2 import SE2Geometry

__all__ = ["RatSLAMConfig"]

_VISUAL_KEYS = tuple(f.name for f in fields(VisualTemplateConfig) if f.name != "emulate_uninitialised_clear")
_VT_DEFAULTS = VisualTemplateConfig()


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
    stores the time since the link's source experience; ``lv_mode`` - how views
    feed the pose cells: ``"stored"`` (OpenRatSLAM's stored location, Eq 5.8;
    default) or ``"learnt"`` (explicit LV->PC weights, Eq 2.17/2.18, with
    ``pc_vt_inject_energy`` as the gain delta).
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
    lv_mode: str = "stored"

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            kind = _field_kinds()[f.name]
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
        if self.lv_mode not in ("stored", "learnt"):
            raise ConfigError(f"lv_mode must be 'stored' or 'learnt', got {self.lv_mode!r}")
        if self.lv_mode == "learnt" and self.pose_cells == "openratslam":
            raise ConfigError("lv_mode='learnt' needs pose_cells='population' (the C++ engine is the stored-location model)")
        if self.pose_cells not in ("population", "openratslam"):
            raise ConfigError(f"pose_cells must be 'population' or 'openratslam', got {self.pose_cells!r}")
        if self.pose_cells == "openratslam" and (self.frame != "openratslam" or self.dtype != "float64"):
            raise ConfigError("pose_cells='openratslam' is the C++ engine: it needs frame='openratslam' and dtype='float64'")
        self.map_config()
        self.map_geometry()
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
        types = _field_kinds()
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
    def attractor_params(self) -> AttractorParams:
        """The pose cells' kernels and global inhibition."""
        return AttractorParams(
            exc_width=self.pc_w_e_dim, exc_sigma=self.pc_w_e_var, inh_width=self.pc_w_i_dim, inh_sigma=self.pc_w_i_var,
            global_inhibition=self.pc_global_inhib,
        )

    def visual_config(self) -> VisualTemplateConfig:
        """The visual front end's parameters."""
        return VisualTemplateConfig(**{k: getattr(self, k) for k in _VISUAL_KEYS})

    def map_config(self) -> MapConfig:
        """The experience map's core parameters."""
        return MapConfig(
            correction=self.exp_correction, relax_passes=self.exp_loops, match_distance_cells=self.exp_delta_pc_threshold,
            pc_shape=(self.pc_dim_xy, self.pc_dim_xy, self.pc_dim_th), offset_axes=(2,), relax_budget=self.relax_budget,
            link_time_since_start=self.link_time_since_start,
        )

    def map_geometry(self) -> SE2Geometry:
        """The experience map's SE(2) geometry (initial heading, panoramic theta axis)."""
        return SE2Geometry(initial_heading_deg=self.exp_initial_em_deg, heading_axis=2, heading_cells=self.pc_dim_th)

    def local_view_params(self) -> LocalViewParams:
        """The local-view cells' parameters: OpenRatSLAM's stored location, or learnt LV->PC weights (``lv_mode``)."""
        if self.lv_mode == "learnt":
            return LocalViewParams(mode="learnt", inject_gain=self.pc_vt_inject_energy, recent_exclusion=0)
        return LocalViewParams(
            mode="stored", inject_energy=self.pc_vt_inject_energy, active_decay=self.vt_active_decay,
            decay_restore=self.pc_vt_restore, recent_exclusion=10, cpp_unsigned_recent=True, rounding="truncate",
            cpp_cells=self.pose_cells == "openratslam",
        )


@functools.lru_cache(maxsize=None)
def _field_kinds() -> dict[str, str]:
    """``{field: "int" | "float" | "bool" | "str" | "int | None"}`` from RatSLAMConfig's type hints."""
    names = {int: "int", float: "float", bool: "bool", str: "str", Optional[int]: "int | None"}
    return {name: names[hint] for name, hint in typing.get_type_hints(RatSLAMConfig).items()}


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

