"""The adapter for OpenRatSLAM's config files: its flat key names -> :class:`~cansim.models.ratslam_config.RatSLAMConfig`.

OpenRatSLAM's ``config_*.txt.in`` files are ``key=value`` lines under ``[section]``
headers; ``#`` and ``;`` start comment lines. This module is the one place that knows
those key names: :data:`OPENRATSLAM_KEYS` maps each onto one field of
:class:`~cansim.models.ratslam_config.RatSLAMConfig`, of its ``attractor``
(:class:`~cansim.params.AttractorParams`) or of its ``frontend``
(:class:`~cansim.frontends.visual.VisualTemplateConfig`; an OpenRatSLAM front end is a
camera). :meth:`RatSLAMConfig.from_file <cansim.models.ratslam_config.RatSLAMConfig.from_file>`
and ``from_text`` delegate here.

==================================  ====================================  =======
OpenRatSLAM key                     cansim field                          default
==================================  ====================================  =======
``pc_dim_xy``                       ``xy_cells``                          21
``pc_dim_th``                       ``heading_cells``                     36
``pc_cell_x_size``                  ``cell_size_m``                       1.0
``pc_w_e_dim``                      ``attractor.exc_width``               7
``pc_w_e_var``                      ``attractor.exc_sigma``               1
``pc_w_i_dim``                      ``attractor.inh_width``               5
``pc_w_i_var``                      ``attractor.inh_sigma``               2
``pc_global_inhib``                 ``attractor.global_inhibition``       2e-5
``pc_cells_to_avg``                 ``decode_window``                     3
``pc_vt_inject_energy``             ``inject_energy``                     0.15
``vt_active_decay``                 ``active_decay``                      1.0
``pc_vt_restore``                   ``decay_restore``                     0.05
``exp_delta_pc_threshold``          ``match_distance_cells``              2.0
``exp_correction``                  ``correction``                        0.5
``exp_loops``                       ``relax_passes``                      10
``exp_initial_em_deg``              ``initial_heading_deg``               90
``template_x_size``                 ``frontend.template_width_blocks``    60
``template_y_size``                 ``frontend.template_height_blocks``   10
``image_crop_x_min``                ``frontend.crop_x_min_px``            0
``image_crop_x_max``                ``frontend.crop_x_max_px``            edge
``image_crop_y_min``                ``frontend.crop_y_min_px``            0
``image_crop_y_max``                ``frontend.crop_y_max_px``            edge
``vt_shift_match``                  ``frontend.shift_match_blocks``       25
``vt_step_match``                   ``frontend.step_match_blocks``        5
``vt_match_threshold``              ``frontend.match_threshold``          0.03
``vt_normalisation``                ``frontend.normalisation_mean``       0
``vt_patch_normalise``              ``frontend.patch_half_width_blocks``  0
``vt_min_patch_normalisation_std``  ``frontend.min_patch_std``            0
``vt_panoramic``                    ``frontend.panoramic``                0
==================================  ====================================  =======

Values: integers may be written ``7`` or ``7.0``; booleans ``1/0``, ``true/false``,
``yes/no``, ``on/off``; a crop maximum of ``-1`` (OpenRatSLAM: the image edge) is
``None``. The keys not in the table (ROS topics, drawing, visual odometry...) are ignored
with one ``UserWarning`` naming them by section and line (``topic_root`` is read by
``cansim replay``, :mod:`cansim.tools.bag_replay`); a malformed value, or one the config refuses (an even kernel
width, a negative size), raises :class:`~cansim.errors.ConfigError` naming the key and
its line.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import replace
from typing import Any, NamedTuple

from cansim.errors import ConfigError, InvalidInputError
from cansim.frontends.visual import VisualTemplateConfig

# The config class is passed in (``config_cls``): ratslam_config imports this module, not the reverse.

__all__ = ["OPENRATSLAM_KEYS", "REPLAY_KEYS", "key_of", "config_from_flat_dict", "read_openratslam_file", "read_openratslam_text", "renamed",
           "write_openratslam_text"]


class _Key(NamedTuple):
    field: str  # "name", "attractor.name" or "frontend.name"
    kind: str  # "int", "float", "bool" or "edge" (an int, -1 = the image edge = None)


OPENRATSLAM_KEYS: dict[str, _Key] = {
    "pc_dim_xy": _Key("xy_cells", "int"),
    "pc_dim_th": _Key("heading_cells", "int"),
    "pc_cell_x_size": _Key("cell_size_m", "float"),
    "pc_w_e_dim": _Key("attractor.exc_width", "int"),
    "pc_w_e_var": _Key("attractor.exc_sigma", "float"),
    "pc_w_i_dim": _Key("attractor.inh_width", "int"),
    "pc_w_i_var": _Key("attractor.inh_sigma", "float"),
    "pc_global_inhib": _Key("attractor.global_inhibition", "float"),
    "pc_cells_to_avg": _Key("decode_window", "int"),
    "pc_vt_inject_energy": _Key("inject_energy", "float"),
    "vt_active_decay": _Key("active_decay", "float"),
    "pc_vt_restore": _Key("decay_restore", "float"),
    "exp_delta_pc_threshold": _Key("match_distance_cells", "float"),
    "exp_correction": _Key("correction", "float"),
    "exp_loops": _Key("relax_passes", "int"),
    "exp_initial_em_deg": _Key("initial_heading_deg", "float"),
    "template_x_size": _Key("frontend.template_width_blocks", "int"),
    "template_y_size": _Key("frontend.template_height_blocks", "int"),
    "image_crop_x_min": _Key("frontend.crop_x_min_px", "int"),
    "image_crop_x_max": _Key("frontend.crop_x_max_px", "edge"),
    "image_crop_y_min": _Key("frontend.crop_y_min_px", "int"),
    "image_crop_y_max": _Key("frontend.crop_y_max_px", "edge"),
    "vt_shift_match": _Key("frontend.shift_match_blocks", "int"),
    "vt_step_match": _Key("frontend.step_match_blocks", "int"),
    "vt_match_threshold": _Key("frontend.match_threshold", "float"),
    "vt_normalisation": _Key("frontend.normalisation_mean", "float"),
    "vt_patch_normalise": _Key("frontend.patch_half_width_blocks", "int"),
    "vt_min_patch_normalisation_std": _Key("frontend.min_patch_std", "float"),
    "vt_panoramic": _Key("frontend.panoramic", "bool"),
}
"""OpenRatSLAM key -> (cansim field, value kind); the table of the module docstring."""

_PARTS = {"attractor": "AttractorParams", "frontend": "VisualTemplateConfig"}


def key_of(field: str) -> str:
    """The OpenRatSLAM config key that sets :class:`RatSLAMConfig`'s ``field`` (``"cell_size_m"`` -> its cell-size
    key), for messages that tell a config file's user what to change; ``field`` itself when no key sets it."""
    return next((k for k, v in OPENRATSLAM_KEYS.items() if v.field == field), field)


def renamed(name: str) -> str | None:
    """How to pass OpenRatSLAM's ``name`` to :class:`RatSLAMConfig` (``"xy_cells=..."``), or None if it is not one of its keys."""
    key = OPENRATSLAM_KEYS.get(name)
    if key is None:
        return None
    part, _, sub = key.field.rpartition(".")
    if not part:
        return f"{sub}=..."
    extra = " (or a TactileTemplateConfig)" if name == "vt_match_threshold" else ""
    return f"{part}={_PARTS[part]}({sub}=...){extra}"


def _parse_value(key: str, value: str, kind: str, lineno: int) -> Any:
    try:
        if kind in ("int", "edge"):
            f = float(value)
            if not f.is_integer():
                raise ValueError
            n = int(f)
            return None if kind == "edge" and n == -1 else n
        if kind == "float":
            f = float(value)
            if not math.isfinite(f):
                raise ValueError
            return f
        low = value.lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise ValueError
    except (ValueError, OverflowError):
        expected = {"int": "an integer", "edge": "an integer (-1 = the image edge)", "float": "a finite number", "bool": "0 or 1"}[kind]
        raise ConfigError(f"line {lineno}: {key}={value!r} is malformed (expected {expected})") from None


def _by_part(values: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """OpenRatSLAM ``{key: value}`` -> ``{"": fields, "attractor": ..., "frontend": ...}`` by the key table."""
    parts: dict[str, dict[str, Any]] = {"": {}, "attractor": {}, "frontend": {}}
    for key, value in values.items():
        part, _, name = OPENRATSLAM_KEYS[key].field.rpartition(".")
        parts[part][name] = value
    return parts


#: Keys of OpenRatSLAM's ``[general]`` section that ``cansim replay`` reads (not the model).
REPLAY_KEYS = ("topic_root",)


def _read(text: str) -> dict[str, tuple[Any, int]]:
    """``{key: (value, line)}`` of the known keys; the unknown keys warned about in one warning, by section."""
    values: dict[str, tuple[Any, int]] = {}
    unused: dict[str, list[str]] = {}  # section -> "key (line n)"
    section = ""
    for lineno, raw in enumerate(text.split("\n"), 1):  # "\n" only: the lines an editor numbers
        line = raw.strip()
        header = line.split(";", 1)[0].split("#", 1)[0].strip()  # "[draw] ; viewer" is a header
        if header.startswith("[") and header.endswith("]"):
            section = header[1:-1].strip()
            continue
        if not line or line.startswith(("#", ";", "[")):
            continue
        if "=" not in line:
            raise ConfigError(f"line {lineno}: {line!r} is not 'key=value'")
        key, value = (s.strip() for s in line.split("=", 1))
        if key not in OPENRATSLAM_KEYS:
            note = " - the bag's topics, read by cansim replay" if key in REPLAY_KEYS else ""
            unused.setdefault(section, []).append(f"{key!r} (line {lineno}{note})")
            continue
        values[key] = (_parse_value(key, value, OPENRATSLAM_KEYS[key].kind, lineno), lineno)
    if unused:
        groups = "; ".join(f"[{sec}] " * bool(sec) + ", ".join(keys) for sec, keys in unused.items())
        n = sum(map(len, unused.values()))
        warnings.warn(f"{n} OpenRatSLAM config key{'s' * (n > 1)} not used by cansim's RatSLAM model (ROS topics, "
                      f"drawing, visual odometry...), ignored: {groups}", UserWarning, stacklevel=4)
    return values


def read_openratslam_text(text: str, config_cls: type, **overrides: Any) -> Any:
    """A :class:`RatSLAMConfig` from the text of an OpenRatSLAM config file.

    Parameters
    ----------
    text : str
        The file's text (see the module docstring).
    config_cls : type
        :class:`RatSLAMConfig` (or a subclass): the class to build.
    **overrides
        RatSLAMConfig fields (cansim names) that replace the file's, e.g.
        ``frontend="ids"`` or ``backend="numpy"``.

    Raises
    ------
    ConfigError
        A line that is not ``key=value``, a malformed value, or a value the config
        refuses (the message names the key and its line); an override that is not a
        field.
    """
    config_cls.check_names(overrides)
    values = _read(text)
    parts = _by_part({key: value for key, (value, _) in values.items()})
    try:  # the file's values first, so that an error is the file's
        cfg = config_cls(
            **parts[""],
            attractor=replace(config_cls().attractor, **parts["attractor"]),
            frontend=VisualTemplateConfig(**parts["frontend"]),
        )
    except InvalidInputError as exc:  # ConfigError, or AttractorParams' own checks
        culprits = [f"{k} (line {line})" for k, (_, line) in values.items() if OPENRATSLAM_KEYS[k].field.split(".")[-1] in str(exc)]
        raise ConfigError(f"OpenRatSLAM config key {', '.join(culprits) or '(a combination of keys)'}: {exc}") from None
    return replace(cfg, **overrides) if overrides else cfg


def write_openratslam_text(config: Any) -> str:
    """The OpenRatSLAM config text (a ``[ratslam]`` section) of a :class:`RatSLAMConfig`.

    Every key of :data:`OPENRATSLAM_KEYS` whose field the config has; the visual
    template's keys only when its front end is a
    :class:`~cansim.frontends.visual.VisualTemplateConfig`. Floats are written exactly
    (``repr``), an image edge (None) as -1 and booleans as 0 / 1, so that
    :func:`read_openratslam_text` gives the same values back (and OpenRatSLAM's C++ reads
    them, e.g. ``bench/cpp_compare.py``'s driver; an integral float is written without
    ``.0`` because OpenRatSLAM reads ``pc_w_e_var`` and ``pc_w_i_var`` as integers).

    Raises
    ------
    ConfigError
        ``config`` is not a RatSLAMConfig.
    """
    if not all(hasattr(config, name) for name in ("xy_cells", "attractor", "frontend")):
        raise ConfigError(f"write_openratslam_text needs a RatSLAMConfig, got {type(config).__name__}")
    lines = ["[ratslam]"]
    for key, (field, kind) in OPENRATSLAM_KEYS.items():
        part, _, name = field.rpartition(".")
        owner = getattr(config, part) if part else config
        if part == "frontend" and not isinstance(owner, VisualTemplateConfig):
            continue
        value = getattr(owner, name)
        if kind == "edge" and value is None:
            text = "-1"
        elif kind == "bool":
            text = "1" if value else "0"
        elif kind == "float":  # integral values without ".0": the C++ reads some of these keys as int
            v = float(value)
            text = str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)
        else:
            text = str(int(value))
        lines.append(f"{key}={text}")
    return "\n".join(lines) + "\n"


def read_openratslam_file(path: str | os.PathLike[str], config_cls: type, **overrides: Any) -> Any:
    """:func:`read_openratslam_text` of a file (UTF-8)."""
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such OpenRatSLAM config file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read it as a text config file ({exc})") from None
    return read_openratslam_text(text, config_cls, **overrides)


def config_from_flat_dict(d: dict[str, Any], config_cls: type) -> Any:
    """A :class:`RatSLAMConfig` from the flat description that cansim 0.x saved before the
    configs had one name per concept (OpenRatSLAM's keys plus ``frontend="ids" | "visual" |
    "tactile"`` and the library settings), so that models saved then still load.

    Parameters
    ----------
    d : dict
        The saved ``config`` mapping (already parsed from JSON).
    config_cls : type
        :class:`RatSLAMConfig` (or a subclass): the class to build.

    Raises
    ------
    ConfigError
        A key that is neither an OpenRatSLAM key nor a field, or a value the config refuses.
    """
    from cansim.frontends.tactile import TactileTemplateConfig

    legacy = {k: None if OPENRATSLAM_KEYS[k].kind == "edge" and v == -1 else v for k, v in d.items() if k in OPENRATSLAM_KEYS}
    parts = _by_part(legacy)
    parts[""].update({k: v for k, v in d.items() if k not in OPENRATSLAM_KEYS})
    kind = parts[""].pop("frontend", "ids")
    if kind == "visual":
        frontend: Any = VisualTemplateConfig(**parts["frontend"])
    elif kind == "tactile":
        frontend = TactileTemplateConfig(**{k: v for k, v in parts["frontend"].items() if k == "match_threshold"})
    elif kind == "ids":
        frontend = "ids"
    else:
        raise ConfigError(f"saved config: frontend must be 'ids', 'visual' or 'tactile', got {kind!r}")
    config_cls.check_names(parts[""])
    try:
        return config_cls(**parts[""], attractor=replace(config_cls().attractor, **parts["attractor"]), frontend=frontend)
    except (InvalidInputError, TypeError) as exc:
        raise ConfigError(f"saved config: {exc}") from None
