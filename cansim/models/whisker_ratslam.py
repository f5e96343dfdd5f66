"""WhiskerRatSLAM (thesis Ch.5, Alg 2): 6-D pose cells, a whisk front end and an object map, composed.

One call per whisk, :meth:`WhiskerRatSLAM.step` ``(odometry, observation) -> SlamState``,
in the order of Alg 2, run by the shared loop :class:`cansim.models.slam_loop.SlamLoop`:

1. match features - the whisk's region (PFH + SDA) against the stored regions, Eq 5.5
   (:class:`cansim.frontends.whisk.WhiskFrontEnd`); a whisk with fewer than 3 contacts
   is no observation (odometry only);
2. feature excitation - stored-location injection, Eq 5.8-5.9: energy
   ``zeta / 30 * (30 - exp(1.2 decay))`` (zeta = 0.3) at the cell stored with the
   region, the region's decay rising on every match and falling back by 0.05 per
   iteration to 0 (:class:`cansim.local_view.LocalViewCells`); or explicit learnt
   LV->PC weights (Eq 2.17/2.18), ``lv_mode="learnt"``;
3. attractor dynamics and 6-D path integration - :meth:`cansim.population.Population.whisker6d`
   (Eq 5.10 kernels; heading-conditional translation: each (roll, pitch, yaw) voxel
   shifts its (x, y, z) block by ``R v dt / cell size``; rotation shifts from omega);
4. best pose - the population vector (Eq 5.11-5.12);
5. process the object map - :class:`maps.object_map.ObjectMap` (SE(3), Alg 6): a new
   experience when the wrapped 6-D cell distance to the current one exceeds
   ``match_distance_cells`` or the region is new, else re-localise to the closest
   experience of the matched region and link; relaxation every iteration.

Odometry is :class:`maps.odometry.SpatialOdometry` (Eq 5.7): ``v`` (3,) m/s and
``omega`` (3,) rad/s in the array's own (end-effector) frame, ``dt`` s.

Decisions where the thesis is silent: the translational cell size defaults to the
typical step between whisks (about one cell per iteration, Ch.3's rule); the stored
location is injected at the nearest cell (OpenRatSLAM truncates, which on a 5-cell axis
biases by up to 72 deg); the experience rule is OpenRatSLAM's (Sec 2.1.2.1), which
contains Ch.5's.

Pose-consistent matching (option, :meth:`WhiskerRatSLAMConfig.mapping`)
-----------------------------------------------------------------------
With the thesis' model alone (:meth:`WhiskerRatSLAMConfig.thesis`, the default) a region
match re-localises wherever the matched region was stored, so on symmetric or flat
objects the model re-localises to aliased places: on the demo's Mug and Box (two loops
of trajectory A, ``examples/whisker_ratslam_object.py``, five seeds) the median
re-localisation error is 0.07-0.24 m on the Mug and 0.64 m (half a turn) on the Box,
against dead-reckoning errors of 0.07-0.14 m and 0.20-0.32 m. The pose cells cannot
veto such a match: one injection of Eq 5.8's energy (0.29 against a packet whose largest
cell holds ~0.001) moves the decoded packet half-way or more to the stored cell at once
(an injection 2 cells away moves it by 1.1 cells), a 5-cell axis wraps every 5 cells,
and the 6-D path integration is not consistent from loop to loop (noise-free odometry
around the Mug or Box puts the packet 1-3 cells and 60-80 deg away from where it was at
the same pose one loop before: on 5-cell angular axes the packet spreads over all
orientations, so heading-conditional translation moves it by 7-27 % of the odometry,
and sub-cell rotations are partly lost to the attractor). The object map's
dead-reckoned pose is consistent, so the model applies RatSLAM's principle - a place is
recognised from the view and the pose belief together - there. For the pose ``x``
predicted by dead reckoning for the current whisk
(:meth:`maps.object_map.ObjectMap.predicted_pose`) and each experience ``e``:

* gate: ``g_e = min(pose_gate_m, pose_gate_growth_m sqrt(n_e))`` (and the same in
  degrees), ``n_e`` = whisks since ``e`` was created. Dead-reckoning error grows like a
  random walk, so the array's own recent trail gets a tight gate (it is not a revisit)
  and a place seen a loop ago a wide one, capped where aliased places begin. A
  re-localisation does not shrink the gate: it matched a region that looks like others
  inside the gate it was accepted in (along a flat face the neighbouring whisk's region
  has the same PFH), so the pose after it is only as certain as that gate. (Decision,
  measured: an earlier rule counted ``n_e`` from the last re-localisation when that was
  fewer; on the Box with the SVR contacts of ``examples/ch5_study.py``, seed 2, the loop
  closed with two re-localisations 4 whisks (0.12 m) early, the reset gate of the next
  whisks (0.06-0.11 m) then rejected the true revisits 0.15-0.19 m away, and later ones
  fell 1-3 deg outside the reset rotation gate, after which dead reckoning drifted to
  0.5 m / 70 deg, out of every gate: 5 re-localisations on loop 2, median one whisk. Counted
  from creation the same run re-localises 44 times, median 0; the study's reduced runs
  (both features + SVR, 2 loops) are at a median of 0 on seeds 0-7 on the Box and the Mug,
  60-76 % of the Box's re-localisations at the exact revisit on seeds 0-5);
* a stored region is a candidate of Eq 5.5 only if one of its experiences lies within
  its gate of ``x`` (position and rotation, Sec 5.2.2.1's distances);
* the match minimises ``chi2 + NMSE + pose_weight (d_e / g_e + angle_e / g_e,deg)``: a
  tie-break toward the pose belief between regions the features cannot tell apart (the
  faces of the Box).

:meth:`WhiskerRatSLAMConfig.mapping` (cap 0.3 m / 60 deg, growth 0.04 m / 12 deg per
square-root whisk - about 4 and 3 standard deviations of the Sec 6.1.3.1.1 odometry
noise of one whisk, 1 cm and 4.3 deg -, weight 2) is what the demo uses: over five seeds at the
demo's contact noise it re-localises on the second loop with a median error of 0 (the
exact revisit) on the Mug and 0-1.5 cm on the Box (step 3 cm; see the demo's docstring
for the figures and their sensitivity). It is not the default: the gate assumes that the
map's frame is the one being explored, while identification (:meth:`WhiskerRatSLAM.library`, Ch.6's
explorer) matches an unknown object against maps in other frames;
:meth:`WhiskerRatSLAM.library` switches the prior off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np

from cansim.errors import ConfigError, CorruptFileError, InvalidInputError
from cansim.frontends.whisk import WhiskFrontEnd, WhiskFrontEndConfig
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.params import AttractorParams
from cansim.population import Population
from cansim.models.slam_config import SlamConfig
from cansim.models.slam_loop import SlamLoop, SlamState, configured
from maps.experience_map import MapConfig
from maps.object_library import ObjectLibrary, append_object_maps
from maps.object_map import ObjectMap
from maps.odometry import SpatialOdometry
from whisker_io.validation import checked

__all__ = ["WhiskerRatSLAM", "WhiskerRatSLAMConfig"]


def _thesis_kernels() -> AttractorParams:
    return AttractorParams(exc_width=5, exc_sigma=1.0, inh_width=5, inh_sigma=math.sqrt(2.0), kernel_normalisation="pdf")


@dataclass(frozen=True)
class WhiskerRatSLAMConfig(SlamConfig):
    """Parameters of WhiskerRatSLAM (defaults: the thesis' Ch.5 model).

    The fields shared with RatSLAM are declared and checked once, in
    :class:`cansim.models.slam_config.SlamConfig`; four of them have this model's own
    defaults here (``cell_size_m``, ``attractor``, ``inject_energy``, ``match_distance_cells``).

    Parameters
    ----------
    grid_cells : int
        Cells on each translational axis (thesis: 5).
    angle_cells : int or None
        Cells on each angular axis (None: ``grid_cells``).
    cell_size_m : float
        Metres per translational cell (not given in the thesis; default 0.1 m, about
        the Ch.5 step between whisks).
    attractor : AttractorParams
        Kernels and global inhibition (Eq 5.10: width 5, variances 1 and 2, printed
        normal densities; phi 2e-5).
    lv_mode : {"stored", "learnt"}
        Stored location (Eq 5.8-5.9, default) or learnt LV->PC weights (Eq 2.17/2.18).
    inject_energy : float
        zeta, the maximum injected energy (0.3); the gain delta in learnt mode.
    active_decay, decay_restore : float
        The decay rise per match (1.0) and fall per iteration (0.05).
    match_distance_cells : float
        Wrapped 6-D pose-cell distance above which a new experience is made (1 cell;
        at most sqrt(24) on 5 cells).
    correction, relax_passes, relax_budget
        Object-map relaxation (Eq 2.25 rate 0.5, 10 passes, at most 2,000 link updates
        per iteration).
    frontend : WhiskFrontEndConfig
        Features (PFH / SDA / both), thresholds T_pfh, T_sda, feature update.
    backend : str
        CAN backend (numba by default).
    dtype : {"float64", "float32"}
    pose_gate_m, pose_gate_deg : float or None
        Pose-consistent matching (module docstring): the largest gate, m and deg, around
        the dead-reckoned pose. None (default, the thesis): no gate. Set both or neither.
    pose_gate_growth_m, pose_gate_growth_deg : float or None
        Gate per square-root whisk since the experience was created (m, deg); None: the
        gate is always the largest. Set both or neither.
    pose_weight : float
        Weight of the gate-normalised pose distance added to ``chi2 + NMSE`` (0: Eq 5.5).
    """

    # shared fields (SlamConfig) with this model's defaults; lv_mode, active_decay,
    # decay_restore, correction, relax_passes, relax_budget, backend, dtype at SlamConfig's
    cell_size_m: float = 0.1
    attractor: AttractorParams = field(default_factory=_thesis_kernels)
    inject_energy: float = 0.3
    match_distance_cells: float = 1.0
    grid_cells: int = checked(5, int, minimum=3)
    angle_cells: int | None = checked(None, int, minimum=3, optional=True, hint="None uses grid_cells")
    frontend: WhiskFrontEndConfig = field(default_factory=WhiskFrontEndConfig)
    pose_gate_m: float | None = checked(None, float, above=0, optional=True)
    pose_gate_deg: float | None = checked(None, float, above=0, maximum=180.0, optional=True)
    pose_gate_growth_m: float | None = checked(None, float, above=0, optional=True)
    pose_gate_growth_deg: float | None = checked(None, float, above=0, maximum=180.0, optional=True)
    pose_weight: float = checked(0.0, float, minimum=0)

    def __post_init__(self) -> None:
        super().__post_init__()  # the declared fields (SlamConfig's and these), the attractor's type
        na = self.grid_cells if self.angle_cells is None else self.angle_cells
        self._check_grid_size(x=self.grid_cells, y=self.grid_cells, z=self.grid_cells, roll=na, pitch=na, yaw=na)
        if not isinstance(self.frontend, WhiskFrontEndConfig):
            raise ConfigError(f"frontend must be a WhiskFrontEndConfig (cansim.frontends.whisk), got {self.frontend!r}")
        self.map_config()
        # pose-consistent matching (module docstring): each gate is a (metres, degrees) pair, both set or both None
        for pair in (("pose_gate_m", "pose_gate_deg"), ("pose_gate_growth_m", "pose_gate_growth_deg")):
            if (getattr(self, pair[0]) is None) != (getattr(self, pair[1]) is None):
                raise ConfigError(f"{pair[0]} and {pair[1]} are both None or both set, got "
                                  f"{(getattr(self, pair[0]), getattr(self, pair[1]))!r}")
        if self.pose_gate_growth_m is not None and self.pose_gate_m is None:
            raise ConfigError("pose_gate_growth_m needs pose_gate_m (the largest gate)")

    @classmethod
    def thesis(cls, **overrides: Any) -> "WhiskerRatSLAMConfig":
        """The Ch.5 model: 5 cells per axis, Eq 5.10 kernels, zeta 0.3, PFH + SDA, Eq 5.5 matching."""
        return cls(**overrides)

    @classmethod
    def mapping(cls, **overrides: Any) -> "WhiskerRatSLAMConfig":
        """The Ch.5 model with pose-consistent matching, for mapping one object in one frame.

        Largest gate 0.3 m / 60 deg, growth 0.04 m / 12 deg per square-root whisk, pose
        weight 2 (module docstring; measured on the demo's Mug and Box). The largest gate
        should exceed the dead-reckoning drift over one loop (0.2-0.3 m / 30 deg there)
        and stay below the rotation between symmetric places of the object (90 deg on the
        Box); the growth is about 4 and 3 sigma of one whisk's odometry noise.
        """
        preset = {"pose_gate_m": 0.3, "pose_gate_deg": 60.0, "pose_gate_growth_m": 0.04, "pose_gate_growth_deg": 12.0,
                  "pose_weight": 2.0}
        return cls(**{**preset, **overrides})

    @property
    def pose_prior(self) -> bool:
        """Whether region matching consults the pose belief (a pose gate is set)."""
        return self.pose_gate_m is not None

    @property
    def shape(self) -> tuple[int, ...]:
        """Pose-cell grid shape (x, y, z, roll, pitch, yaw)."""
        na = self.grid_cells if self.angle_cells is None else self.angle_cells
        return (self.grid_cells,) * 3 + (na,) * 3

    def map_config(self) -> MapConfig:
        """The object map's core parameters."""
        return MapConfig(
            correction=self.correction, relax_passes=self.relax_passes, match_distance_cells=self.match_distance_cells,
            pc_shape=self.shape, offset_axes=(), relax_budget=self.relax_budget, keep_first_accumulator=False,
        )

    def local_view_params(self) -> LocalViewParams:
        """The region -> pose-cell connection (the thesis' decay rule in stored mode)."""
        if self.lv_mode == "learnt":
            return LocalViewParams(mode="learnt", inject_energy=self.inject_energy, recent_exclusion=0)
        return LocalViewParams(
            mode="stored", inject_energy=self.inject_energy, active_decay=self.active_decay, decay_restore=self.decay_restore,
            decay_floor=0.0, rise_on_every_match=True, decay_per_iteration=True, recent_exclusion=0, rounding="round",
        )

    @classmethod
    def _fields_from_dict(cls, d: dict[str, Any]) -> dict[str, Any]:
        d = super()._fields_from_dict(d)
        if isinstance(d.get("frontend"), dict):
            d["frontend"] = WhiskFrontEndConfig(**d["frontend"])
        return d


def _positive_dt(odo: SpatialOdometry) -> None:
    if odo.dt <= 0:
        raise InvalidInputError(f"a whisk's odometry needs dt > 0 s, got {odo.dt!r}")


#: Configuration fields every model of :meth:`WhiskerRatSLAM.library` shares with the exploring configuration: the
#: pose-cell grid and the region matching (features, thresholds), without which the maps' cells and stored regions
#: would not mean the same thing. The cell size may differ: the Ch.5 study maps each object at its own step and
#: explores at the presented object's (:func:`cansim.studies.ch5_object_maps.library_model`).
_LIBRARY_FIELDS = ("grid_cells", "angle_cells", "lv_mode", "frontend")


class WhiskerRatSLAM(SlamLoop):
    """The 6-DoF WhiskerRatSLAM model (see the module docstring).

    Parameters
    ----------
    config : WhiskerRatSLAMConfig, optional
        Parameters; keyword arguments override its fields (``WhiskerRatSLAM(cell_size_m=0.03)``).

    Examples
    --------
    >>> import numpy as np
    >>> slam = WhiskerRatSLAM(backend="numpy")
    >>> s = slam.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.2], 1.0), None)  # a whisk without contact
    >>> s.exp_id
    -1
    """

    def __init__(self, config: WhiskerRatSLAMConfig | None = None, **params: Any) -> None:
        cfg = self.config = configured(WhiskerRatSLAMConfig, config, params)
        na = cfg.grid_cells if cfg.angle_cells is None else cfg.angle_cells
        pose_cells = Population.whisker6d(
            cfg.grid_cells, cfg.cell_size_m, angle_cells=na, params=cfg.attractor, backend=cfg.backend, dtype=np.dtype(cfg.dtype)
        )
        super().__init__(
            pose_cells,
            LocalViewCells(pose_cells.shape, cfg.local_view_params()),
            WhiskFrontEnd(cfg.frontend, pose_prior=self._region_prior if cfg.pose_prior else None),
            ObjectMap(cfg.map_config()),
            SpatialOdometry,
            check_odometry=_positive_dt,
        )
        self._predicted: np.ndarray | None = None  # dead-reckoned pose of the whisk being matched
        self._warm = False  # warm_up() has run (the first step runs it)

    @property
    def object_map(self) -> ObjectMap:
        """The object map (an :class:`~maps.object_map.ObjectMap`)."""
        return self.experience_map  # type: ignore[return-value]

    def step(self, *args: Any) -> SlamState:  # type: ignore[override]
        """One whisk: ``step(odometry, observation)`` or ``step(v (3,), omega (3,), dt, observation)``.

        Parameters
        ----------
        odometry : SpatialOdometry
            Body-frame ``v`` m/s, ``omega`` rad/s (rotation-vector rate) and ``dt`` s since
            the previous whisk (Eq 5.7).
        observation : RegionFeatures, (pfh, sda) tuple or None
            The whisk's region; None, or a region with fewer than 3 contacts
            (``is_observation`` False), is a whisk without observation.

        Returns
        -------
        SlamState
            ``best_pc`` in cells (x, y, z, roll, pitch, yaw); ``map_pose`` =
            ``(x, y, z m, qx, qy, qz, qw)`` of the current experience.

        Raises
        ------
        InvalidInputError, ShapeError
            Bad odometry (non-finite, wrong shapes, ``dt <= 0``: a whisk takes time) or a
            malformed region; the model is unchanged.
        """
        if len(args) not in (2, 4):
            raise InvalidInputError("step takes (odometry, observation) or (v, omega, dt, observation)")
        if not getattr(self, "_warm", True):
            self.warm_up()
        *odo_args, observation = args
        if observation is not None and getattr(observation, "is_observation", True) is False:
            observation = None
        odo = self.odometry(*odo_args)
        if observation is not None and self.config.pose_prior:
            self._predicted = self.object_map.predicted_pose(odo)
        try:
            state = super().step(odo, observation)
        finally:
            self._predicted = None
        points = getattr(observation, "contact_points_m", None)
        if points is not None and self.object_map.n_experiences:  # what was felt, for maps.surface_match
            self.object_map.record_contacts(points)
        return state

    def warm_up(self, *, progress: bool = False) -> float:
        """Compile (or load from the disk cache) every kernel this configuration uses, now.

        Runs a short scripted exploration on a fresh model of the same configuration
        (:func:`cansim.models.warm_up.warm_up_whisker`); this model is unchanged. The first
        :meth:`step` calls it when it has not run, so no kernel compiles inside the loop.
        Logs a line (and with ``progress`` shows one on stderr) when it takes more than a second.

        Returns
        -------
        float
            Seconds taken (s).
        """
        from cansim.models.warm_up import warm_up_whisker

        self._warm = True
        return warm_up_whisker(self, progress=progress)

    def _advance(self, odo: Any, view_id: int = -1, new_view: bool = False) -> SlamState:
        """The odometry part of an iteration (from :meth:`step` and :meth:`on_odo` alike), then the
        object map's history: one entry per iteration, so ``history`` and ``iteration`` agree."""
        state = super()._advance(odo, view_id, new_view)
        self.object_map.record()
        return state

    def _region_prior(self, n_regions: int) -> tuple[np.ndarray, np.ndarray]:
        """Pose-consistent regions and their pose cost (the module docstring's gate and weight)."""
        cfg, om = self.config, self.object_map
        if self._predicted is None:  # matching outside step(): no pose belief to consult
            return np.ones(n_regions, dtype=bool), np.zeros(n_regions)
        gate_m, gate_rad = float(cfg.pose_gate_m), math.radians(float(cfg.pose_gate_deg))  # type: ignore[arg-type]
        n = om.n_experiences
        if cfg.pose_gate_growth_m is not None:
            root = np.sqrt((om.n_recorded - om.creation_iterations).astype(np.float64))
            gates_m = np.minimum(gate_m, cfg.pose_gate_growth_m * root)
            gates_rad = np.minimum(gate_rad, math.radians(float(cfg.pose_gate_growth_deg)) * root)  # type: ignore[arg-type]
        else:
            gates_m, gates_rad = np.full(n, gate_m), np.full(n, gate_rad)
        consistent, cost = om.gated_views(self._predicted, gates_m, gates_rad, n_regions)
        return consistent, cfg.pose_weight * cost  # the weight >= 0 commutes with the minimum

    @classmethod
    def library(
        cls, models: Sequence["WhiskerRatSLAM"], names: Sequence[str], config: WhiskerRatSLAMConfig | None = None,
        warn_empty: bool = True,
    ) -> tuple["WhiskerRatSLAM", ObjectLibrary]:
        """One model holding the object maps of several models, for identification (Fig 5.16).

        The stored regions and their pose-cell locations are appended in order; the object
        maps are appended with :func:`maps.object_library.append_object_maps` (ids shifted,
        no link between objects). The pose cells start from the initial packet and every
        region's decay at the floor, as for an array brought to an unknown object, so the
        model has no pose prior: the configuration's pose-consistent matching is switched
        off (the maps are in other frames than the exploration). The appended map runs
        with the exploring configuration's map parameters (:meth:`WhiskerRatSLAMConfig.map_config`,
        e.g. its ``match_distance_cells``); the grid must be the maps'.

        Parameters
        ----------
        models : sequence of WhiskerRatSLAM
            The objects' models (stored-location mode, the same grid and front end).
        names : sequence of str
            Object names, in the order of ``models``.
        config : WhiskerRatSLAMConfig, optional
            Of the exploring model (default: the first model's).
        warn_empty : bool
            Warn of a model whose map holds no experience (:func:`~maps.object_library.append_object_maps`);
            False where the caller says it itself.

        Returns
        -------
        (WhiskerRatSLAM, ObjectLibrary)
            The model and the experience -> object table. Save both to resume an
            identification: the model with :meth:`save`, the table (names included) with
            :meth:`~maps.object_library.ObjectLibrary.save`.

        Raises
        ------
        InvalidInputError
            Not one model per name, one model under two names, or a model whose grid,
            local-view mode or front end (features, thresholds) differs from the exploring
            configuration's (the maps would not mean the same thing; the cell size may differ).
        """
        if not models or len(models) != len(names) or not all(isinstance(m, WhiskerRatSLAM) for m in models):
            raise InvalidInputError("library needs one WhiskerRatSLAM per name (at least one)")
        if len({id(m) for m in models}) < len(models):
            raise InvalidInputError("library got one model under two names; give each object's own model once")
        cfg = config if config is not None else models[0].config
        for k, m in enumerate(models):  # one metric grid, one region matching: else the maps mean different things
            other = [f for f in _LIBRARY_FIELDS if getattr(m.config, f) != getattr(cfg, f)]
            if other:
                raise InvalidInputError(
                    f"the model of {names[k]!r} differs from the {'given' if config is not None else 'first'} "
                    f"configuration in {', '.join(other)}; build every object's map with one grid and front end and "
                    "explore with them")
        model = cls(replace(cfg, pose_gate_m=None, pose_gate_deg=None, pose_gate_growth_m=None, pose_gate_growth_deg=None,
                            pose_weight=0.0))
        offsets = []
        for m in models:
            offsets.append(model.frontend.extend(m.frontend))
            model.local_view.extend_stored(m.local_view)
        lib = append_object_maps([m.object_map for m in models], names, offsets, warn_empty=warn_empty)
        if tuple(lib.object_map.config.pc_shape) != model.config.shape:
            raise InvalidInputError(f"the maps' pose-cell grid {lib.object_map.config.pc_shape} is not the exploring "
                                    f"configuration's {model.config.shape}; use one grid")
        lib.object_map.config = model.config.map_config()  # a new map: the exploring model's parameters
        model.experience_map = lib.object_map
        return model, lib

    # ------------------------------------------------------- save / resume
    def describe(self) -> dict[str, Any]:
        """The configuration, for :meth:`save`."""
        return {"model": "WhiskerRatSLAM", "config": self.config.to_dict()}

    @classmethod
    def from_description(cls, description: dict[str, Any]) -> "WhiskerRatSLAM":
        """An empty model from :meth:`describe` output."""
        if description.get("model") != "WhiskerRatSLAM":
            raise ValueError(f"the file holds a {description.get('model')!r} model, not WhiskerRatSLAM")
        try:
            return cls(WhiskerRatSLAMConfig.from_dict(description["config"]))
        except (ConfigError, CorruptFileError) as exc:
            raise ValueError(str(exc)) from exc
