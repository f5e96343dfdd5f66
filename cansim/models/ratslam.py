"""RatSLAM (3-DoF): a composition of pose cells, local-view cells, a front end and an SE(2) experience map.

The loop itself (order of the calls, save / resume) is :class:`cansim.models.slam_loop.SlamLoop`;
this module only wires the parts from a :class:`~cansim.models.ratslam_config.RatSLAMConfig`
(OpenRatSLAM's config files are read by :mod:`cansim.models.openratslam_config`):

1. front end, selected by ``frontend`` - precomputed view ids ("ids",
   :class:`~cansim.frontends.ids.IdsFrontEnd`), camera images (a ``VisualTemplateConfig``,
   :class:`~cansim.frontends.visual.VisualTemplates`) or the 3 x 6 tactile image of thesis
   Ch.3 (a ``TactileTemplateConfig``, :class:`~cansim.frontends.tactile.TactileTemplates`);
2. local-view cells - OpenRatSLAM's stored location (``PosecellNetwork::on_view_template``:
   C++ truncation, no injection for the 10 most recent templates - with fewer than 10
   every revisit injects, as C++'s unsigned arithmetic does - and the decay rules) or
   explicit learnt LV->PC weights (Eq 2.17/2.18), ``lv_mode``;
3. pose cells - :class:`cansim.population.Population` (any backend and dtype), in the
   parity preset :class:`cansim.models.posecell_network.PosecellNetwork`, or (opt-in,
   ``pose_cells="spiking"``) :class:`cansim.models.spiking_pose_cells.SpikingPoseCells`;
4. map - :class:`maps.experience_map.ExperienceMap` with :class:`maps.se2.SE2Geometry`.

Parity preset (:meth:`RatSLAMConfig.openratslam`): the C++ pose-cell engine (the C++
arithmetic in the C++ order, float64), the C++ frame (theta index 0 moves the packet
along +y), C++ view-cell arithmetic (raw stored coordinates, theta wrapped once,
truncation, out-of-grid cells skipped), OpenRatSLAM's unbounded relaxation and
never-reset link timer, and translation limited to one cell per step - the C++
four-weight shift is only valid up to one cell, so larger steps raise
:class:`InvalidInputError` (reduce the speed or raise ``cell_size_m``). Fed the same
odometry and view ids (with panoramic ``relative_rad``) as OpenRatSLAM's C++ core driven
the way its ROS nodes drive it, every step's decoded (x, y, theta), experience id, action
and the final map are bit-identical (``tests/data/openratslam_cpp_trace.csv``). Remaining
differences, all outside the core: OpenRatSLAM's ROS nodes drop the first odometry
message (it has no previous time stamp) while every step's ``dt`` is used here - skip
your first sample to match; the C++ constructor never initialises ``vt_delta_pc_th``,
which ``get_action`` reads when a view among the 10 most recent is revisited before any
view has injected - cansim starts it at 0, what a fresh heap holds; the C++ bugs of the
visual front end are listed (and emulable) in :mod:`cansim.frontends.visual`. With
``pose_cells="population"`` the same model runs on cansim's generic engine and agrees
to ~1e-15 cells per step until a truncated coordinate falls the other way.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from cansim.errors import ConfigError, InvalidInputError
from cansim.frontends.ids import IdsFrontEnd
from cansim.frontends.panoramic import HeadingOffset
from cansim.frontends.store import ViewMatch
from cansim.frontends.tactile import TactileTemplateConfig, TactileTemplates
from cansim.frontends.visual import VisualTemplateConfig, VisualTemplates
from cansim.local_view import LocalViewCells
from cansim.population import Population
from cansim.models.openratslam_config import key_of
from cansim.models.posecell_network import PosecellNetwork
from cansim.models.ratslam_config import RatSLAMConfig
from cansim.models.slam_loop import SlamLog, SlamLoop, SlamState, configured
from maps.experience_map import ExperienceMap
from maps.odometry import PlanarOdometry
from whisker_io.validation import caller_stacklevel

__all__ = ["RatSLAM", "RatSLAMConfig"]


class RatSLAM(SlamLoop):
    """RatSLAM with OpenRatSLAM semantics (see the module docstring).

    Parameters
    ----------
    config : RatSLAMConfig, optional
        Parameters; keyword arguments (its field names) override it
        (``RatSLAM(xy_cells=30, relax_passes=3)``). OpenRatSLAM's key names raise
        :class:`ConfigError` naming the field; read OpenRatSLAM files with
        :meth:`RatSLAMConfig.from_file`.

    Examples
    --------
    >>> slam = RatSLAM(cell_size_m=0.1)
    >>> s = slam.step(0.05, 0.0, 1.0, 0)      # 5 cm/s for 1 s, view id 0
    >>> s.exp_id
    0
    """

    def __init__(self, config: RatSLAMConfig | None = None, **params: Any) -> None:
        cfg = self.config = configured(RatSLAMConfig, config, params)
        pose_cells: Any
        if cfg.pose_cells == "spiking":  # opt-in; imported here so that the rate engines import nothing spiking
            from cansim.models.spiking_pose_cells import SpikingPoseCellParams, SpikingPoseCells

            pose_cells = SpikingPoseCells(cfg.xy_cells, cfg.heading_cells, cfg.cell_size_m,
                                          cfg.spiking if cfg.spiking is not None else SpikingPoseCellParams(), frame=cfg.frame)
        elif cfg.pose_cells == "openratslam":
            pose_cells = PosecellNetwork(
                cfg.xy_cells, cfg.heading_cells, cfg.cell_size_m, params=cfg.attractor, decode_window=cfg.decode_window,
            )
        else:
            pose_cells = Population.openratslam(
                cfg.xy_cells, cfg.heading_cells, cfg.cell_size_m, frame=cfg.frame, params=cfg.attractor,
                dtype=np.dtype(cfg.dtype), backend=cfg.backend, decode_window=cfg.decode_window,
            )
        frontend: Any
        if isinstance(cfg.frontend, VisualTemplateConfig):
            frontend = HeadingOffset(VisualTemplates(cfg.frontend), 3, 2, cfg.heading_cells)
        elif isinstance(cfg.frontend, TactileTemplateConfig):
            frontend = HeadingOffset(TactileTemplates(cfg.frontend), 3, 2, cfg.heading_cells)
        else:
            frontend = IdsFrontEnd(3, heading_axis=2, heading_cells=cfg.heading_cells)
        super().__init__(
            pose_cells,
            LocalViewCells(pose_cells.shape, cfg.local_view_params()),
            frontend,
            ExperienceMap(cfg.map_config(), cfg.map_geometry()),
            PlanarOdometry,
            check_odometry=self._check,
            refuse_odometry=self._refuse,
        )
        self._warm = False  # warm_up() has run (the first step or run runs it)
        self._one_cell_m = cfg.cell_size_m * (1 + 1e-12)
        self._quarter_grid_m = cfg.xy_cells * cfg.cell_size_m / 4  # a step this long is no robot's: units?
        self._warned: set[str] = set()  # the implausible-odometry warnings given (once each per model)
        self._strict, self._spiking = bool(cfg.strict_translation), cfg.pose_cells == "spiking"

    def _refuse(self, odo: PlanarOdometry) -> None:
        """The odometry this model refuses, with no side effect (``run`` checks every sample with it first): a step of
        more than one cell with ``strict_translation``; a sample of no duration for the spiking pose cells (they run
        for ``dt`` of network time)."""
        if self._spiking and not odo.dt > 0:
            raise InvalidInputError(f"dt = {odo.dt:g} s: the spiking pose cells need dt > 0 (they run for dt of network "
                                    "time); merge or drop odometry samples with equal timestamps")
        if self._strict:
            step_m = abs(odo.v * odo.dt)
            if step_m > self._one_cell_m:
                raise InvalidInputError(
                    f"vtrans*dt = {odo.v * odo.dt:g} m moves the packet {step_m / self.config.cell_size_m:.3g} cells; "
                    "OpenRatSLAM's path integration is valid for at most one cell per step - "
                    f"raise cell_size_m ({key_of('cell_size_m')} in an OpenRatSLAM config file) or split the step"
                )

    def _check(self, odo: PlanarOdometry) -> None:
        """:meth:`_refuse`, then a warning (once each) of a turn of more than half a circle in one step and, without
        ``strict_translation``, of a step that moves the packet a quarter of the grid or more."""
        if self._spiking or self._strict:
            self._refuse(odo)
        if abs(odo.omega * odo.dt) > math.pi or (not self._strict and abs(odo.v * odo.dt) >= self._quarter_grid_m):
            self._warn_implausible(odo)

    def _warn_implausible(self, odo: PlanarOdometry) -> None:
        turn_rad, move_m = odo.omega * odo.dt, abs(odo.v * odo.dt)
        if abs(turn_rad) > math.pi and "turn" not in self._warned:
            self._warned.add("turn")
            warnings.warn(f"iteration {self.iteration}: vrot*dt = {turn_rad:g} rad turns more than half a circle in one "
                          "step (the pose cells cannot tell the way it turned); vrot is in rad/s - a yaw rate in deg/s? "
                          "(this warning is given once)", UserWarning, stacklevel=caller_stacklevel())
        if move_m >= self._quarter_grid_m and "move" not in self._warned:
            self._warned.add("move")
            cells = move_m / self.config.cell_size_m
            grid_m = self.config.xy_cells * self.config.cell_size_m
            warnings.warn(f"iteration {self.iteration}: vtrans*dt = {move_m:g} m moves the packet {cells:.3g} cells in one "
                          f"step, a quarter of the {self.config.xy_cells}-cell grid or more ({grid_m / 2:g} m, half the "
                          "grid, wraps round to another place) - check the units (m/s, s), raise cell_size_m or split "
                          "the step (this warning is given once)", UserWarning, stacklevel=caller_stacklevel())

    def step(self, vtrans: float, vrot: float, dt: float, observation: Any = None) -> SlamState:  # type: ignore[override]
        """Run one RatSLAM iteration: the view (if an observation is given), then the odometry.

        Parameters
        ----------
        vtrans : float
            Forward speed, m/s.
        vrot : float
            Yaw rate, rad/s (counter-clockwise positive).
        dt : float
            Duration of the odometry sample, s.
        observation : int, tuple, ndarray or None
            ``frontend="ids"``: a view id (any non-negative integer; first-seen order
            numbers the views) or a ``(view_id, relative_rad)`` pair - the rotation (rad)
            of a panoramic match, OpenRatSLAM's ``ViewTemplate`` message; a
            ``VisualTemplateConfig`` front end: a uint8 image; a ``TactileTemplateConfig``:
            a 3 x 6 tactile image; None: odometry only.

        Returns
        -------
        SlamState

        Raises
        ------
        InvalidInputError, ShapeError
            Bad odometry (NaN, negative dt, > 1 cell/step in strict mode) or a bad
            observation; the model is unchanged.
        """
        if not self._warm:
            self.warm_up(observation)
        return super().step(vtrans, vrot, dt, observation)

    def on_view(self, observation: Any) -> ViewMatch:
        """:meth:`SlamLoop.on_view <cansim.models.slam_loop.SlamLoop.on_view>`, after the warm-up
        when none has run (a loop of :meth:`on_view` / :meth:`on_odo` calls, e.g. bag replay, warms
        up at its first view, with that view)."""
        if not self._warm:
            self.warm_up(observation)
        return super().on_view(observation)

    def warm_up(self, observation: Any = None, *, progress: bool = False) -> float:
        """Compile (or load from the disk cache) every kernel this configuration uses, now.

        Runs a short scripted circle on a fresh model of the same configuration
        (:func:`cansim.models.warm_up.warm_up_ratslam`); this model is unchanged. The first
        :meth:`step` or :meth:`run` calls it (with its first observation, so an image front
        end compiles for the images' dtype) when it has not run, so no kernel compiles
        inside the loop; so does the first :meth:`on_view` of a loop of :meth:`on_view` /
        :meth:`on_odo` calls (bag replay). Logs a line (and with ``progress`` shows one on stderr)
        when it takes more than a second.

        Parameters
        ----------
        observation : optional
            An observation of the kind the loop will give (e.g. one camera image).
        progress : bool
            Show a progress line on stderr when it takes more than a second.

        Returns
        -------
        float
            Seconds taken (s).
        """
        from cansim.models.warm_up import warm_up_ratslam

        elapsed = warm_up_ratslam(self, observation, progress=progress)
        self._warm = True  # only once it ran: a refused observation leaves the model as it was
        return elapsed

    def run(self, vtrans: Any, vrot: Any, dt: Any, observations: Any, *, progress: bool = False) -> SlamLog:  # type: ignore[override]
        """:meth:`step` for every row: ``vtrans``, ``vrot`` (n,) m/s and rad/s, ``dt`` s (scalar or (n,))."""
        n = len(vtrans)
        if len(vrot) != n or len(observations) != n:
            raise InvalidInputError(f"vtrans, vrot and observations must have the same length, got {n}, {len(vrot)}, {len(observations)}")
        try:
            dts = np.broadcast_to(np.asarray(dt, dtype=np.float64), (n,))
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"dt must be a number or one per sample ({n}), s: {exc}") from None
        try:
            samples = [(float(vtrans[k]), float(vrot[k]), float(dts[k])) for k in range(n)]
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"vtrans and vrot must be numbers (m/s, rad/s), one per sample: {exc}") from None
        self._checked_samples(samples)  # refused before the warm-up (seconds with spiking pose cells) and any sample
        if not self._warm:
            self.warm_up(next((o for o in observations if o is not None), None), progress=progress)
        return self._run_checked(samples, observations, progress)  # lengths checked above

    # ------------------------------------------------------- save / resume
    def extra_arrays(self) -> dict[str, np.ndarray]:
        """The spiking pose cells' state (``pose_cells="spiking"``; nothing for the rate engines)."""
        if self.config.pose_cells == "spiking":
            return self.pose_cells.state_arrays("spc_")
        return {}

    def restore_extra(self, arrays: Any) -> None:
        """Restore what :meth:`extra_arrays` wrote."""
        if self.config.pose_cells == "spiking":
            self.pose_cells.restore_state(arrays, "spc_")

    def describe(self) -> dict[str, Any]:
        """The configuration, for :meth:`save`."""
        return {"model": "RatSLAM", "config": self.config.to_dict()}

    @classmethod
    def from_description(cls, description: dict[str, Any]) -> "RatSLAM":
        """An empty model from :meth:`describe` output."""
        if description.get("model") != "RatSLAM":
            raise ValueError(f"the file holds a {description.get('model')!r} model, not RatSLAM")
        try:
            return cls(RatSLAMConfig.from_dict(description["config"]))
        except ConfigError as exc:
            raise ValueError(str(exc)) from exc
