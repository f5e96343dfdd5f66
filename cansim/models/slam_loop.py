"""The one SLAM loop: front end -> local-view cells -> pose cells -> map, for any composition.

RatSLAM (3-DoF) and WhiskerRatSLAM (6-DoF) are compositions of four parts behind
small protocols, run by :class:`SlamLoop` in OpenRatSLAM's order (Alg 2 of the thesis
for the 6-D model):

1. :meth:`SlamLoop.on_view` - the front end turns the observation into a view
   (:class:`~cansim.frontends.store.ViewMatch`: view id, new or known, per-axis
   ``offset_cells``); the local-view cells (:class:`~cansim.local_view.LocalViewCells`,
   stored-location mode, Eq 5.8, or learnt LV->PC weights, Eq 2.17/2.18) turn a known
   view into energy, queued for the pose cells;
2. :meth:`SlamLoop.on_odo` - the queued energy is injected, the pose cells run their
   dynamics and path integration and decode the packet (:class:`PoseCells`); in learnt
   mode the active view learns the new packet (Eq 2.18); the map dead-reckons the
   odometry and, once both a view and an odometry update have arrived, creates, links
   or re-localises experiences and relaxes (:class:`maps.experience_map.ExperienceMap`).

:meth:`SlamLoop.step` is ``on_view`` (when an observation is given) then ``on_odo``;
:meth:`SlamLoop.run` steps through a sequence; :meth:`SlamLoop.save` /
:meth:`SlamLoop.load` persist everything so that a resumed run equals an
uninterrupted one. Odometry is a :class:`maps.odometry.PlanarOdometry` or
:class:`maps.odometry.SpatialOdometry`, validated once when it enters the loop.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Protocol, Sequence

import numpy as np

from cansim.errors import CansimError, CorruptFileError, InvalidInputError, UnknownBackendError
from cansim.frontends.store import ViewMatch
from cansim.local_view import LocalViewCells
from maps.experience_map import Action, ExperienceMap
from maps.odometry import Odometry
from whisker_io.persistence import naming_file, read_npz, write_npz

__all__ = ["FrontEnd", "PoseCells", "SlamLoop", "SlamLog", "SlamState", "configured"]

_NO_INDEX = np.zeros(0, dtype=np.int64)
_NO_VALUES = np.zeros(0, dtype=np.float64)
_LOOP_FORMAT = 1


def configured(config_type: type, config: Any, params: dict[str, Any]) -> Any:
    """A model's configuration: ``config`` (or the defaults) with keyword overrides; a key that names no
    field is refused by the configuration class (:class:`whisker_io.validation.ConfigDataclass`)."""
    cfg = config if config is not None else config_type()
    return dataclasses.replace(cfg, **params) if params else cfg


class PoseCells(Protocol):
    """What the loop needs of a pose-cell engine (:class:`~cansim.population.Population`,
    :class:`~cansim.models.posecell_network.PosecellNetwork`).

    An engine may also have ``_step_validated``, ``step`` for odometry fields that were
    validated already (:meth:`cansim.population.Population._step_validated`); the loop
    then calls it, so each odometry sample is checked once."""

    shape: tuple[int, ...]
    size: int
    dtype: np.dtype
    activity: np.ndarray

    def decode(self) -> np.ndarray: ...

    def step(self, velocity: Any, omega: Any, dt: float, *, injection: Any = None) -> np.ndarray: ...


class FrontEnd(Protocol):
    """An observation matcher: ``match`` returns a :class:`ViewMatch` (validating first),
    ``to_arrays`` / ``from_arrays`` persist its state."""

    def match(self, observation: Any) -> ViewMatch: ...

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]: ...

    def from_arrays(self, arrays: dict[str, np.ndarray], prefix: str) -> None: ...


@dataclass(frozen=True)
class SlamState:
    """What one :meth:`SlamLoop.step` produced.

    Attributes
    ----------
    iteration : int
        Number of odometry updates done, this one included.
    best_pc : tuple of float
        Decoded packet, fractional pose cells (one per axis).
    exp_id : int
        Current experience (-1 before the first one).
    relocalised : bool
        The current experience switched to an existing, different one this step.
    action : Action
        The map's action this step.
    map_pose : tuple of float
        Map pose of the current experience (SE(2): x m, y m, theta rad; SE(3): x, y, z m
        and the quaternion xyzw).
    view_id : int
        The view of this step (-1 when no observation was given).
    new_view : bool
        The observation became a new view.
    """

    iteration: int
    best_pc: tuple[float, ...]
    exp_id: int
    relocalised: bool
    action: Action
    map_pose: tuple[float, ...]
    view_id: int
    new_view: bool


@dataclass(frozen=True)
class SlamLog:
    """Per-iteration record of :meth:`SlamLoop.run`; row k is iteration k of the run.

    Attributes
    ----------
    exp_ids : ndarray (n,) int64
        Current experience (the Experience Metric's experience log, Alg 1).
    relocalised : ndarray (n,) bool
    best_pc : ndarray (n, ndim)
        Decoded packet, fractional cells.
    view_ids : ndarray (n,) int64
        View (-1 without observation).
    """

    exp_ids: np.ndarray
    relocalised: np.ndarray
    best_pc: np.ndarray
    view_ids: np.ndarray



def _at_sample(exc: CansimError, k: int, applied: str) -> None:
    """Prefix ``exc``'s message with the run's sample ``k`` and say what was ``applied``, in place: the same error
    (its class and its data, e.g. a corrupt file's path) re-raised by the caller."""
    if exc.args and isinstance(exc.args[0], str):
        exc.args = (f"sample {k}: {exc.args[0]}; {applied}", *exc.args[1:])

class SlamLoop:
    """Runs a composition of front end, local-view cells, pose cells and map.

    Parameters
    ----------
    pose_cells : PoseCells
    local_view : LocalViewCells
        Wired to ``pose_cells.shape``; its ``mode`` chooses stored-location or learnt injection.
    frontend : FrontEnd
    experience_map : ExperienceMap
        Its ``pc_shape`` must be the pose cells' shape.
    odometry : type
        :class:`~maps.odometry.PlanarOdometry` or :class:`~maps.odometry.SpatialOdometry`:
        the kind of odometry the parts take (``step``'s arguments build one).
    check_odometry : callable, optional
        Extra model-specific check of a validated odometry (raises InvalidInputError; may warn).
    refuse_odometry : callable, optional
        The part of ``check_odometry`` that raises, with no side effect (no warning): :meth:`run` checks every
        sample with it before the first is applied. Default: ``check_odometry`` itself.
    """

    def __init__(
        self,
        pose_cells: PoseCells,
        local_view: LocalViewCells,
        frontend: FrontEnd,
        experience_map: ExperienceMap,
        odometry: type,
        check_odometry: Callable[[Odometry], None] | None = None,
        refuse_odometry: Callable[[Odometry], None] | None = None,
    ) -> None:
        if tuple(local_view.shape) != tuple(pose_cells.shape) or tuple(experience_map.config.pc_shape) != tuple(pose_cells.shape):
            raise InvalidInputError(
                f"parts disagree on the pose grid: pose cells {pose_cells.shape}, local view "
                f"{local_view.shape}, map {experience_map.config.pc_shape}"
            )
        self.pose_cells = pose_cells
        self.local_view = local_view
        self.frontend = frontend
        self.experience_map = experience_map
        self._odometry = odometry
        self._check = check_odometry
        self._refuse = refuse_odometry if refuse_odometry is not None else check_odometry
        ndim = len(pose_cells.shape)
        self._best = np.asarray(pose_cells.decode(), dtype=np.float64)
        self.iteration = 0
        self._current_vt = 0
        self._prev_vt = 0
        self._offset = np.zeros(ndim)
        self._odo_update = False
        self._vt_update = False
        self._learn_pending = False
        self._viewed = False
        self._pending_index, self._pending_values = _NO_INDEX, _NO_VALUES

    # -------------------------------------------------------------- views
    @property
    def best_pc(self) -> tuple[float, ...]:
        """Last decoded packet, fractional cells."""
        return tuple(self._best.tolist())  # Python floats, as float(v) of each

    @property
    def n_views(self) -> int:
        """Number of local-view cells."""
        return self.local_view.n_views

    def odometry(self, *args: Any) -> Odometry:
        """Validate ``step``'s odometry arguments (or pass a ready odometry object of the right kind through)."""
        kind = self._odometry
        if len(args) == 1:
            odo = args[0]
            if not isinstance(odo, kind):
                raise InvalidInputError(f"odometry must be a {kind.__name__} or its fields, got {type(odo).__name__}")
        else:
            odo = kind(*args)
        if self._check is not None:
            self._check(odo)
        return odo

    # --------------------------------------------------------------- step
    def on_view(self, observation: Any) -> ViewMatch:
        """A view update alone: match, then queue the view's energy for the next :meth:`on_odo`.

        Raises
        ------
        InvalidInputError, ShapeError
            A malformed observation; the model is unchanged.
        """
        match = self.frontend.match(observation)  # validates before any state changes
        off = match.offset_cells
        index, values = self.local_view.observe(match.view_id, self._best, offset_cells=off)
        if self.local_view.last_energy > 0:  # C++ sets vt_delta_pc_th whenever energy > 0, injected or not
            self._offset = np.zeros(len(self._best)) if off is None else np.array(off, dtype=np.float64)
        if len(index):
            self._pending_index = np.concatenate([self._pending_index, index])
            self._pending_values = np.concatenate([self._pending_values, values])
        self._prev_vt, self._current_vt = self._current_vt, match.view_id
        self._vt_update = True
        self._viewed = True
        self._learn_pending = self.local_view.params.mode == "learnt"
        return match

    def on_odo(self, *odometry: Any) -> SlamState:
        """An odometry update alone (pose cells, learning, map); see :meth:`step`."""
        return self._advance(self.odometry(*odometry))

    def _advance(self, odo: Odometry, view_id: int = -1, new_view: bool = False) -> SlamState:
        """The odometry part of an iteration, for an odometry that :meth:`odometry` checked
        (``view_id`` / ``new_view``: this iteration's view, for the returned state)."""
        injection = (self._pending_index, self._pending_values) if len(self._pending_index) else None
        # the odometry object is validated: an engine with a trusted step skips the second check
        step = getattr(self.pose_cells, "_step_validated", None) or self.pose_cells.step
        best = step(odo.v, odo.omega, odo.dt, injection=injection)
        self._best = np.asarray(best, dtype=np.float64)
        self._pending_index, self._pending_values = _NO_INDEX, _NO_VALUES
        if self._learn_pending:  # Eq 2.18: the active view learns the packet it now sees
            self.local_view.learn(self.pose_cells.activity)
            self._learn_pending = False
        if not self._viewed and self.local_view.params.decay_per_iteration:
            self.local_view.restore_decay()
        self._viewed = False
        self._odo_update = True
        self.iteration += 1
        em = self.experience_map
        em.on_odo(odo)
        result = None
        if self._odo_update and self._vt_update and self.local_view.n_views > 0:
            self._odo_update = self._vt_update = False
            result = em.update(self._best, self._current_vt, self._prev_vt, offset_cells=self._offset)
        return SlamState(
            iteration=self.iteration,
            best_pc=self.best_pc,
            exp_id=em.current_id if em.n_experiences else -1,
            relocalised=bool(result.relocalised) if result else False,
            action=result.action if result else Action.NO_ACTION,
            map_pose=em.current_pose(),
            view_id=view_id,
            new_view=new_view,
        )

    def step(self, *args: Any) -> SlamState:
        """One iteration: :meth:`on_view` (when an observation is given), then :meth:`on_odo`.

        Parameters
        ----------
        *args
            ``(odometry, observation)`` with an odometry object, or the odometry's
            fields followed by the observation: planar ``(v m/s, omega rad/s, dt s,
            observation)``, spatial ``(v (3,), omega (3,), dt, observation)``. The
            observation may be None (odometry only).

        Raises
        ------
        InvalidInputError, ShapeError
            Bad odometry or observation; the model is unchanged.
        """
        if not args:
            raise InvalidInputError("step needs odometry (and optionally an observation)")
        *odo_args, observation = args if len(args) in (2, 4) else (*args, None)
        odo = self.odometry(*odo_args)  # before the view changes anything
        if observation is None:
            return self._advance(odo)
        match = self.on_view(observation)
        return self._advance(odo, match.view_id, bool(match.is_new))

    def run(self, odometry: Sequence[Any], observations: Sequence[Any], *, progress: bool = False) -> SlamLog:
        """Call :meth:`step` for every (odometry, observation) pair.

        Parameters
        ----------
        odometry : sequence of odometry objects or of argument tuples, length n
        observations : sequence of length n (None entries allowed)
        progress : bool
            Show a tqdm progress bar.
        """
        n = len(odometry)
        if len(observations) != n:
            raise InvalidInputError(f"odometry and observations must have the same length, got {n} and {len(observations)}")
        self._checked_samples(odometry)  # every sample's odometry refused or taken before the first is applied
        return self._run_checked(odometry, observations, progress)

    def _run_checked(self, odometry: Sequence[Any], observations: Sequence[Any], progress: bool) -> SlamLog:
        """:meth:`run`'s loop, for samples :meth:`_checked_samples` took (and as many observations)."""
        n = len(odometry)
        exp_ids = np.empty(n, dtype=np.int64)
        reloc = np.empty(n, dtype=bool)
        best = np.empty((n, len(self._best)))
        vids = np.empty(n, dtype=np.int64)
        rows: Any = range(n)
        if progress:
            from tqdm import tqdm

            rows = tqdm(rows, desc=type(self).__name__, unit="it")
        for k in rows:
            obs = observations[k]
            if isinstance(obs, np.integer):
                obs = int(obs)
            o = odometry[k]
            try:
                s = self.step(*(o if isinstance(o, tuple) else (o,)), obs)
            except CansimError as exc:  # an observation (only a step reads it)
                _at_sample(exc, k, f"samples 0-{k - 1} were applied: the model holds their state" if k else
                           "nothing was applied")
                raise
            exp_ids[k], reloc[k], best[k], vids[k] = s.exp_id, s.relocalised, s.best_pc, s.view_id
        return SlamLog(exp_ids=exp_ids, relocalised=reloc, best_pc=best, view_ids=vids)

    def _checked_samples(self, odometry: Sequence[Any]) -> list[Odometry]:
        """Every sample's odometry object (built from its fields), each refused as :meth:`step` would refuse it
        (``refuse_odometry``), before any is applied; an error names its sample."""
        kind, out = self._odometry, []
        for k, o in enumerate(odometry):
            try:
                try:
                    odo = o if isinstance(o, kind) else kind(*(o if isinstance(o, tuple) else (o,)))
                except TypeError as exc:  # a sample of the wrong number of fields
                    raise InvalidInputError(f"odometry sample must be a {kind.__name__} or its fields: {exc}") from None
                if self._refuse is not None:
                    self._refuse(odo)
            except CansimError as exc:
                _at_sample(exc, k, "nothing was applied")
                raise
            out.append(odo)
        return out

    # ------------------------------------------------------- save / resume
    def describe(self) -> dict[str, Any]:
        """JSON-able description that :meth:`from_description` turns back into an empty model.

        Model classes (``RatSLAM``, ...) implement it; a bare loop cannot be saved.
        """
        raise InvalidInputError(f"{type(self).__name__} cannot be saved: compose it through a model class that implements describe()")

    @classmethod
    def from_description(cls, description: dict[str, Any]) -> "SlamLoop":
        """Build an empty model from :meth:`describe` output."""
        raise InvalidInputError(f"{cls.__name__} cannot be loaded: use the model class that saved the file")

    def save(self, path: str | os.PathLike[str]) -> None:
        """Save the whole model (pose cells, views, front end, map) to an ``.npz`` file.

        Loading it with :meth:`load` and continuing gives exactly the same results as an
        uninterrupted run. No pickle: arrays plus a JSON string. As :func:`numpy.savez`,
        ``.npz`` is added to a name without it (``save("run")`` writes ``run.npz``, which
        ``load("run")`` reads); the file is written whole, then renamed into place, so a
        crash never leaves half a file under its name (:func:`whisker_io.persistence.write_npz`).
        """
        arrays: dict[str, Any] = {
            "loop_format": np.int64(_LOOP_FORMAT),
            "model": np.array(json.dumps(self.describe())),
            "pc_activity": self.pose_cells.activity,
            "pc_best": np.asarray(self._best, dtype=np.float64),
            "loop_i": np.array(
                [self.iteration, self._current_vt, self._prev_vt, int(self._odo_update), int(self._vt_update),
                 int(self._learn_pending), int(self._viewed)], dtype=np.int64),
            "loop_offset": self._offset.copy(),
            "pending_index": self._pending_index,
            "pending_values": self._pending_values,
        }
        arrays.update(self.local_view.to_arrays(prefix="lv_"))
        arrays.update(self.experience_map.to_arrays(prefix="em_"))
        arrays.update(self.frontend.to_arrays(prefix="vt_"))
        arrays.update(self.extra_arrays())
        write_npz(path, arrays)

    def extra_arrays(self) -> dict[str, np.ndarray]:
        """Model-specific state for :meth:`save` (none here); :meth:`restore_extra` reads it back."""
        return {}

    def restore_extra(self, arrays: Mapping[str, np.ndarray]) -> None:
        """Restore what :meth:`extra_arrays` wrote (raises CorruptFileError naming a bad field)."""

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "SlamLoop":
        """Load a model written by :meth:`save`.

        Raises
        ------
        CorruptFileError
            The file is unreadable, or a field is missing or malformed (named in the error).
        """
        arrays = read_npz(path)
        with naming_file(path):  # a fault met while rebuilding names the file
            return cls.from_arrays(arrays)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> "SlamLoop":
        """Rebuild a model from the arrays :meth:`save` writes."""

        def need(key: str) -> np.ndarray:
            if key not in arrays:
                raise CorruptFileError("missing", field=key)
            return np.asarray(arrays[key])

        if "model" not in arrays and "format" in arrays and "link_ends" in arrays:
            raise CorruptFileError(f"this file holds an experience map (ExperienceMap.save, or the experience_map.npz "
                                   f"of cansim replay), not a whole {cls.__name__} model: read it with "
                                   "maps.experience_map.ExperienceMap.load")
        if "model" not in arrays and "exp_object" in arrays and "names" in arrays:
            raise CorruptFileError(f"this file holds an object library (ObjectLibrary.save: which experience belongs to "
                                   f"which object), not a whole {cls.__name__} model: read it with "
                                   "maps.object_library.ObjectLibrary.load")
        if "model" not in arrays and "schema.json" in arrays:
            raise CorruptFileError(f"this file is a scikit-learn model (.skops: a Ch.4 radial-distance model), not a "
                                   f"{cls.__name__} model: load it with whisker_io.radial.persistence.load_model")
        if "loop_format" in arrays:  # files before it had the same layout
            fmt = np.asarray(arrays["loop_format"])
            if fmt.shape != () or fmt.dtype.kind not in "iu" or int(fmt) != _LOOP_FORMAT:
                raise CorruptFileError(f"layout {fmt.tolist()!r}, this version reads {_LOOP_FORMAT} (a file of another "
                                       "cansim version: load it there and re-save, or rebuild the model)",
                                       field="loop_format")
        description = need("model")
        try:
            parsed = json.loads(str(description))
        except (json.JSONDecodeError, TypeError, ValueError) as exc:
            raise CorruptFileError(f"not a valid model description ({exc})", field="model") from exc
        if not isinstance(parsed, dict):
            raise CorruptFileError(f"not a model description (a JSON object), got {type(parsed).__name__}", field="model")
        saved_backend = parsed["config"].get("backend") if isinstance(parsed.get("config"), dict) else None
        from cansim.backends import registered_backends

        if isinstance(saved_backend, str) and saved_backend not in registered_backends():  # not the file's fault
            raise UnknownBackendError(f"this model was saved with the backend {saved_backend!r}, which is not registered in "
                                      "this process: cansim.backends.register_backend: register it before loading a "
                                      "model saved with it")
        try:
            model = cls.from_description(parsed)
        except (json.JSONDecodeError, TypeError, KeyError, ValueError) as exc:
            raise CorruptFileError(f"not a valid model description ({exc})", field="model") from exc
        pc = model.pose_cells
        act, best = need("pc_activity"), need("pc_best")
        if act.shape != pc.shape or act.dtype != pc.dtype:
            raise CorruptFileError(f"shape/dtype {act.shape}/{act.dtype}, expected {pc.shape}/{pc.dtype}", field="pc_activity")
        try:
            pc.activity = act
        except InvalidInputError as exc:
            raise CorruptFileError(str(exc), field="pc_activity") from exc
        nd = len(pc.shape)
        if best.shape != (nd,) or not np.all(np.isfinite(best)):
            raise CorruptFileError(f"expected {nd} finite numbers", field="pc_best")
        li, off = need("loop_i"), need("loop_offset")
        if li.shape != (7,) or li.dtype.kind != "i":
            raise CorruptFileError("expected 7 integers", field="loop_i")
        if off.shape != (nd,) or not np.all(np.isfinite(off)):
            raise CorruptFileError(f"expected {nd} finite numbers", field="loop_offset")
        model.local_view = LocalViewCells.from_arrays(dict(arrays), model.local_view.params, prefix="lv_")
        model.experience_map = type(model.experience_map).from_arrays(arrays, prefix="em_")
        model.frontend.from_arrays(dict(arrays), prefix="vt_")
        model._best = np.array(best, dtype=np.float64)
        if hasattr(pc, "best"):
            pc.best = model._best
        model.iteration, model._current_vt, model._prev_vt = int(li[0]), int(li[1]), int(li[2])
        model._odo_update, model._vt_update, model._learn_pending, model._viewed = (bool(v) for v in li[3:7])
        model._offset = np.array(off, dtype=np.float64)
        p_idx, p_val = need("pending_index"), need("pending_values")
        if p_idx.ndim != 1 or p_idx.shape != p_val.shape or p_idx.dtype.kind != "i" or (len(p_idx) and (p_idx.min() < 0 or p_idx.max() >= pc.size)):
            raise CorruptFileError("expected matching 1-D index/value arrays of pose-cell indices", field="pending_index")
        model._pending_index, model._pending_values = p_idx.astype(np.int64), p_val.astype(np.float64)
        model.restore_extra(arrays)
        return model

