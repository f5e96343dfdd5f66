"""Local-view (LV) cells and their connection to a pose-cell population (Eq 2.17/2.18, Eq 5.8).

LV cells form a growing population, one cell per distinct template/observation
(the view id given by a front end). Two ways of feeding them back into the pose
cells are provided:

``mode="stored"`` (OpenRatSLAM's simplification, thesis Sec 2.1.2.1.2, Eq 5.8)
    each view remembers the decoded pose-cell location at its creation; when it is
    seen again, energy ``Omega = zeta / 30 * (30 - exp(1.2 * decay))`` (clamped at 0)
    is injected into that one cell. ``decay`` rises by ``active_decay`` when the
    same view is seen twice in a row and falls by ``decay_restore`` after every view
    call, floored at ``active_decay`` - a view seen on every step loses influence.
    The thesis' 6-D rule (Eq 5.8-5.9) is selectable: ``rise_on_every_match=True`` and
    ``decay_floor=0`` - the energy is taken at the current decay, which then rises by
    ``active_decay`` on every match and falls back by ``decay_restore`` per iteration
    to 0 (maximum energy 29/30 zeta).
    Views among the ``recent_exclusion`` (10) most recent do not inject, with the C++
    unsigned-arithmetic quirk (while fewer than 10 views exist, every revisit injects)
    reproduced when ``cpp_unsigned_recent=True`` (default).

``mode="learnt"`` (Milford & Wyeth 2008, thesis Eq 2.17/2.18)
    an explicit non-negative weight matrix ``beta`` (n_views x n_cells), stored sparse
    (one sorted index/value row per view; :attr:`weights` gives a scipy CSR matrix),
    learnt by ``beta_i <- max(beta_i, lambda * V_i * P)`` and injected as
    ``dP = (delta / eta_act) * sum_i beta_i V_i`` with ``eta_act`` the number of
    active views.

The view activity vector ``V`` (1 for the current view, optionally decaying traces
of earlier views) is public state (:attr:`activity`) so experiments can record it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from cansim._renamed import renamed_keywords
from cansim.errors import ConfigError, CorruptFileError, InvalidInputError, ShapeError
from whisker_io.validation import ConfigDataclass, checked, finite_array, finite_vector, validate_fields

__all__ = ["LocalViewParams", "LocalViewCells", "stored_injection_energy"]


_LN_30 = math.log(30.0)


def stored_injection_energy(decay: float, max_energy: float) -> float:
    """Eq 5.8 / OpenRatSLAM: ``zeta / 30 * (30 - exp(1.2 * decay))``, clamped at 0.

    Parameters
    ----------
    decay : float
        The view's decay value (>= the decay floor).
    max_energy : float
        zeta, the maximum injection (``inject_energy``; OpenRatSLAM ``pc_vt_inject_energy`` 0.15, Ch.5 0.3).

    Returns
    -------
    float
        Energy added to one pose cell; 0 from ``decay >= ln(30)/1.2 = 2.834`` (also for
        a decay so large that the exponential would overflow: a view seen hundreds
        of times in a row, where C++'s ``exp`` gives inf).
    """
    if 1.2 * decay >= _LN_30:
        return 0.0
    return max(0.0, max_energy / 30.0 * (30.0 - math.exp(1.2 * decay)))


@renamed_keywords(inject_gain="inject_energy")
@dataclass(frozen=True)
class LocalViewParams(ConfigDataclass):
    """Parameters of the LV -> pose-cell connection.

    Parameters
    ----------
    mode : {"stored", "learnt"}
        Injection model (see module docstring).
    inject_energy : float
        The injected energy, as in the models' configs: in stored mode zeta, the maximum
        energy of Eq 5.8 (OpenRatSLAM ``pc_vt_inject_energy``, default 0.15; Ch.5 uses
        0.3); in learnt mode delta of Eq 2.17, the energy per unit of learnt weight
        (0.1's ``inject_gain``, which still works until 0.3 with a DeprecationWarning).
    active_decay : float
        Decay increment on a match (OpenRatSLAM ``vt_active_decay``, 1.0).
    decay_restore : float
        Decay recovery per view call or :meth:`LocalViewCells.restore_decay` (OpenRatSLAM
        ``pc_vt_restore``, 0.05).
    decay_floor : float or None
        Lowest decay, also a new view's decay; None = ``active_decay`` (OpenRatSLAM). The
        thesis' 6-D model uses 0.
    rise_on_every_match : bool
        False (OpenRatSLAM): the decay rises only when the previous view is seen again,
        before the energy is computed. True (thesis Ch.5): the energy is computed at the
        current decay, which then rises on every match.
    decay_per_iteration : bool
        False (OpenRatSLAM): the decay recovers once per view call. True (thesis Ch.5):
        also on iterations without an observation (the model loop calls
        :meth:`LocalViewCells.restore_decay`).
    recent_exclusion : int
        Views among this many most recent ones do not inject (OpenRatSLAM 10; 0 disables).
    cpp_unsigned_recent : bool
        Reproduce C++'s ``vt < size - 10`` in unsigned arithmetic: with fewer than
        ``recent_exclusion`` views every revisit injects.
    rounding : {"truncate", "round"}
        How the stored fractional location becomes a cell: C++ truncates (``(int)``),
        ``"round"`` takes the nearest cell. Default ``"truncate"`` (OpenRatSLAM).
    cpp_cells : bool
        OpenRatSLAM's exact cell arithmetic for 3-D (x, y, theta) grids: the view
        keeps the decoded location as it is (C++ ``find_best`` returns values in
        ``[0, n]``, so ``n`` itself can occur); the theta offset is added and
        wrapped once (``< 0: + n``, ``>= n: - n``) even when it is 0; x and y are
        not wrapped; a truncated cell outside the grid injects nothing (C++
        ``inject``'s bounds check). Default False: locations wrap into ``[0, n)``.
    learning_rate : float
        lambda of Eq 2.18 (learnt mode).
    trace_decay : float
        In [0, 1): each view call multiplies V by this before the current view is set
        to 1 (0 = only the current view is active).
    min_weight : float
        Learnt mode: cells with ``P < min_weight * max(P)`` are not stored (0 = exact
        Eq 2.18). Rows are stored as int32 indices and float32 weights (8 bytes per
        entry: a 6-D 5^6 packet of ~3,300 cells costs ~27 kB per view).
    """

    mode: str = "stored"
    inject_energy: float = checked(0.15, float, minimum=0)
    active_decay: float = checked(1.0, float, minimum=0)
    decay_restore: float = checked(0.05, float, minimum=0)
    decay_floor: Optional[float] = checked(None, float, minimum=0, optional=True)
    rise_on_every_match: bool = checked(False, bool)
    decay_per_iteration: bool = checked(False, bool)
    recent_exclusion: int = checked(10, int, minimum=0)
    cpp_unsigned_recent: bool = checked(True, bool)
    rounding: str = "truncate"
    cpp_cells: bool = checked(False, bool)
    learning_rate: float = checked(1.0, float, minimum=0)
    trace_decay: float = checked(0.0, float, minimum=0)  # and < 1: checked in __post_init__
    min_weight: float = checked(0.0, float, minimum=0)  # and < 1: checked in __post_init__

    def __post_init__(self) -> None:
        validate_fields(self)  # the declared fields; numpy scalars -> Python numbers
        if self.mode not in ("stored", "learnt"):
            raise InvalidInputError(f"mode must be 'stored' or 'learnt', got {self.mode!r}")
        if self.rounding not in ("truncate", "round"):
            raise InvalidInputError(f"rounding must be 'truncate' or 'round', got {self.rounding!r}")
        for name in ("min_weight", "trace_decay"):
            if not getattr(self, name) < 1.0:
                raise ConfigError(f"{name} must lie in [0, 1), got {getattr(self, name)!r}")
        if self.cpp_cells and (self.mode != "stored" or self.rounding != "truncate"):
            raise InvalidInputError("cpp_cells reproduces OpenRatSLAM's stored-mode truncation; use mode='stored', rounding='truncate'")

    @property
    def inject_gain(self) -> float:
        """Deprecated name of :attr:`inject_energy` (learnt mode's delta); goes in 0.3."""
        warnings.warn("LocalViewParams.inject_gain is now inject_energy (renamed before the first release, the old name goes in 0.3)",
                      DeprecationWarning, stacklevel=2)
        return self.inject_energy


#: largest learnt weight the float32 rows hold
_WEIGHT_MAX = float(np.finfo(np.float32).max)

Injection = tuple[np.ndarray, np.ndarray]
_EMPTY: Injection = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float64))


class LocalViewCells:
    """A growing set of LV cells wired to a pose-cell grid of shape ``pose_shape``.

    Parameters
    ----------
    pose_shape : tuple of int
        Shape of the pose-cell population the views inject into.
    params : LocalViewParams

    Examples
    --------
    >>> from cansim import Population
    >>> pc = Population.openratslam()
    >>> lv = LocalViewCells(pc.shape)
    >>> inj = lv.observe(0, pc.decode())       # new view: remembers the packet, injects nothing
    >>> _ = pc.step(0.0, 0.0, 1.0, injection=inj)
    """

    def __init__(self, pose_shape: Sequence[int], params: LocalViewParams = LocalViewParams()) -> None:
        self._shape = tuple(int(n) for n in pose_shape)
        if not self._shape or any(n < 1 for n in self._shape):
            raise ShapeError(f"pose_shape must be a non-empty tuple of positive sizes, got {pose_shape!r}")
        self._params = params
        self._floor = params.active_decay if params.decay_floor is None else params.decay_floor
        if params.cpp_cells and len(self._shape) != 3:
            raise ShapeError(f"cpp_cells needs a 3-D (x, y, theta) pose grid, got shape {self._shape}")
        self._n_cells = int(np.prod(self._shape))
        if self._n_cells >= 2**31:
            raise ShapeError(f"pose grids of 2**31 cells or more are not supported (got {self._n_cells})")
        self._locations: list[np.ndarray] = []  # stored mode: fractional cell per view
        self._decay_buf = np.zeros(16, dtype=np.float64)  # growable; the first n_views entries are live
        self._n = 0
        self._rows: list[tuple[np.ndarray, np.ndarray]] = []  # learnt mode: (indices, values)
        self._v = np.zeros(0, dtype=np.float64)
        self._current: Optional[int] = None
        self.last_energy = 0.0
        """Stored mode: energy of the last :meth:`observe` (0 when nothing was due; C++ ``energy``)."""

    # ---------------------------------------------------------------- state
    @property
    def params(self) -> LocalViewParams:
        """The parameters."""
        return self._params

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the pose-cell grid the views inject into."""
        return self._shape

    @property
    def n_views(self) -> int:
        """Number of LV cells created so far."""
        return self._n

    @property
    def _decay(self) -> np.ndarray:
        return self._decay_buf[: self._n]

    @property
    def current(self) -> Optional[int]:
        """Id of the most recently observed view (None before the first)."""
        return self._current

    @property
    def activity(self) -> np.ndarray:
        """The view activity vector V, shape (n_views,) (a copy)."""
        return self._v.copy()

    @property
    def decay(self) -> np.ndarray:
        """Stored-mode decay of every view, shape (n_views,) (a copy)."""
        return self._decay.copy()

    @property
    def locations(self) -> np.ndarray:
        """Stored-mode pose-cell location (fractional cells) of every view, shape (n_views, ndim)."""
        if not self._locations:
            return np.zeros((0, len(self._shape)))
        return np.stack(self._locations)

    @property
    def weights(self):
        """Learnt LV->PC weights beta as a ``scipy.sparse.csr_matrix`` (n_views x n_cells)."""
        from scipy.sparse import csr_matrix

        indptr = np.zeros(self.n_views + 1, dtype=np.int64)
        for i, (idx, _) in enumerate(self._rows):
            indptr[i + 1] = indptr[i] + len(idx)
        if self._rows:
            indices = np.concatenate([r[0] for r in self._rows])
            data = np.concatenate([r[1] for r in self._rows])
        else:
            indices = np.zeros(0, dtype=np.int64)
            data = np.zeros(0, dtype=np.float64)
        return csr_matrix((data, indices, indptr), shape=(self.n_views, self._n_cells))

    # --------------------------------------------------------------- update
    def observe(
        self,
        view_id: int,
        decoded: Sequence[float],
        *,
        offset_cells: Optional[Sequence[float]] = None,
    ) -> Injection:
        """Activate ``view_id`` and return the energy it injects into the pose cells.

        Parameters
        ----------
        view_id : int
            An existing view (``< n_views``) or the next new one (``== n_views``).
        decoded : sequence of float, shape (ndim,)
            The current decoded pose-cell location (fractional cells); a new view
            remembers it (stored mode).
        offset_cells : sequence of float or None
            Added to the stored location before injection, per axis (OpenRatSLAM's
            panoramic ``vt_rad`` correction on the theta axis), wrapped.

        Returns
        -------
        (flat_index, values) : (ndarray int64, ndarray float64)
            Pass as ``injection=`` to :meth:`Population.step` (empty when nothing is injected).

        Raises
        ------
        InvalidInputError
            ``view_id`` skips ids or is negative, or ``decoded`` is not finite; nothing changed.
        """
        vid = self._check_view(view_id)
        loc = finite_vector(np.ravel(decoded) if isinstance(decoded, np.ndarray) else decoded, len(self._shape), "decoded location")
        off = None
        if offset_cells is not None:
            off = finite_vector(offset_cells, len(self._shape), "offset_cells")
            if max(map(abs, off.tolist()), default=0.0) > 1e6:  # a few values: no numpy reduction per step
                raise InvalidInputError(f"offset_cells beyond +-1e6 cells are not an offset, got {off.tolist()}")

        p = self._params
        injection = _EMPTY
        self.last_energy = 0.0
        if vid == self.n_views:
            self._locations.append(loc.copy() if p.cpp_cells else loc % np.array(self._shape))
            if self._n == len(self._decay_buf):
                self._decay_buf = np.concatenate([self._decay_buf, np.zeros(len(self._decay_buf))])
            self._decay_buf[self._n] = self._floor
            self._n += 1
            self._rows.append((np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)))
            self._v = np.append(self._v, 0.0)
        elif p.mode == "stored":
            injection = self._stored_injection(vid, off)
        # learnt mode injects after V is updated (below)

        self._v *= p.trace_decay
        self._v[vid] = 1.0
        if p.mode == "learnt":
            injection = self.injection()
        if p.mode == "stored":
            self.restore_decay()
        self._current = vid
        return injection

    def extend_stored(self, other: "LocalViewCells") -> int:
        """Append ``other``'s views (stored-location mode) after this population's.

        The appended views keep their stored pose-cell locations; their decay starts at
        the floor and they are inactive (an object library, Fig 5.16). Returns the id
        offset of ``other``'s views here.
        """
        if not isinstance(other, LocalViewCells) or other.shape != self.shape:
            raise ShapeError("extend_stored needs LocalViewCells on the same pose grid")
        if self._params.mode != "stored" or other.params.mode != "stored":
            raise InvalidInputError("extend_stored joins stored-location views only (mode='stored')")
        offset, m = self._n, other.n_views
        self._locations.extend(loc.copy() for loc in other._locations)
        need = offset + m
        if need > len(self._decay_buf):
            self._decay_buf = np.concatenate([self._decay_buf, np.zeros(need)])
        self._decay_buf[offset:need] = self._floor
        self._n = need
        self._rows.extend((np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.float32)) for _ in range(m))
        self._v = np.concatenate([self._v, np.zeros(m)])
        return offset

    def restore_decay(self) -> None:
        """Every view's decay falls by ``decay_restore``, down to the floor (done by every
        :meth:`observe`; call it on iterations without an observation when the decay runs
        per iteration, as in the thesis' 6-D model)."""
        d = self._decay
        np.maximum(d - self._params.decay_restore, self._floor, out=d)

    def _check_view(self, view_id: int) -> int:
        if isinstance(view_id, (bool, np.bool_)) or not isinstance(view_id, (int, np.integer)):
            raise InvalidInputError(f"view_id must be an integer, got {view_id!r}")
        vid = int(view_id)
        if vid < 0 or vid > self.n_views:
            raise InvalidInputError(
                f"view_id {vid} is neither an existing view (< {self.n_views}) nor the next new one "
                f"({self.n_views}); front ends must number views consecutively"
            )
        return vid

    def _stored_injection(self, vid: int, off: Optional[np.ndarray]) -> Injection:
        p = self._params
        n = self.n_views
        limit = n - p.recent_exclusion
        if p.cpp_unsigned_recent and limit < 0:
            limit = n  # C++ unsigned wrap-around: every existing view qualifies
        if not vid < limit:
            return _EMPTY
        if p.rise_on_every_match:
            energy = stored_injection_energy(self._decay[vid], p.inject_energy)
            self._decay[vid] += p.active_decay
        else:
            if vid == self._current:
                self._decay[vid] += p.active_decay
            energy = stored_injection_energy(self._decay[vid], p.inject_energy)
        if energy <= 0.0:
            return _EMPTY
        self.last_energy = energy
        if p.cpp_cells:
            return self._cpp_injection(vid, off, energy)
        loc = self._locations[vid] if off is None else (self._locations[vid] + off) % np.array(self._shape)
        to_cell = math.floor if p.rounding == "truncate" else round  # round: nearest, ties to even as np.rint
        flat = 0
        for c, n in zip(loc.tolist(), self._shape):  # C-order flat index of the wrapped cell
            flat = flat * n + int(to_cell(c)) % n
        return np.array([flat], dtype=np.int64), np.array([energy])

    def _cpp_injection(self, vid: int, off: Optional[np.ndarray], energy: float) -> Injection:
        """OpenRatSLAM ``on_view_template``'s cell: theta corrected and wrapped once, ``(int)``, bounds-checked."""
        nx, ny, nth = self._shape
        x, y, th = self._locations[vid].tolist()
        th = th + (float(off[2]) if off is not None else 0.0)
        if th < 0:
            th = nth + th
        if th >= nth:
            th = th - nth
        cx, cy, ct = int(x), int(y), int(th)  # int() truncates toward zero like C++ (int)
        if not (0 <= cx < nx and 0 <= cy < ny and 0 <= ct < nth):
            return _EMPTY
        return np.array([(cx * ny + cy) * nth + ct], dtype=np.int64), np.array([energy])

    def injection(self) -> Injection:
        """Learnt mode, Eq 2.17: ``(delta / eta_act) * sum_i beta_i V_i`` as (flat_index, values), delta = ``inject_energy``."""
        active = np.flatnonzero(self._v > 0)
        if len(active) == 0:
            return _EMPTY
        gain = self._params.inject_energy / len(active)
        idx = [self._rows[i][0] for i in active]
        val = [self._rows[i][1] * (gain * self._v[i]) for i in active]
        return np.concatenate(idx).astype(np.int64), np.concatenate(val).astype(np.float64)

    def learn(self, pose_activity: np.ndarray) -> None:
        """Eq 2.18 for every active view: ``beta_i <- max(beta_i, lambda * V_i * P)``.

        Parameters
        ----------
        pose_activity : ndarray, shape ``pose_shape``
            The pose-cell activity P (sparse after global inhibition; only its non-zero
            cells are stored).

        Raises
        ------
        ShapeError, InvalidInputError
            ``pose_activity`` of another shape, not numbers, NaN/inf or negative, or a weight
            beyond the float32 range of the stored rows; nothing changed.
        """
        flatP = finite_array(pose_activity, self._shape, "pose_activity").ravel()
        if np.any(flatP < 0):
            raise InvalidInputError("pose_activity must be finite and >= 0")
        cut = self._params.min_weight * float(flatP.max(initial=0.0))
        nz = np.flatnonzero(flatP > cut)
        vals = flatP[nz].astype(np.float64)
        lam = self._params.learning_rate
        biggest = lam * float(self._v.max(initial=0.0)) * float(vals.max(initial=0.0))
        if not biggest <= _WEIGHT_MAX:  # the rows store float32 weights (validate before any row changes)
            raise InvalidInputError(
                f"a learnt weight of {biggest:g} (learning_rate x view activity x pose activity) exceeds the float32 "
                f"range of the stored weights ({_WEIGHT_MAX:g}); lower learning_rate or normalise pose_activity"
            )
        for i in np.flatnonzero(self._v > 0):
            self._rows[i] = _max_merge(self._rows[i], (nz, lam * self._v[i] * vals))

    # ------------------------------------------------------------ persistence
    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """All state as named arrays (for ``np.savez``); :meth:`from_arrays` restores it exactly."""
        w = self.weights
        arrays = {
            "shape": np.array(self._shape, dtype=np.int64),
            "locations": self.locations,
            "decay": self.decay,
            "v": self._v.copy(),
            "current": np.array(-1 if self._current is None else self._current, dtype=np.int64),
            "w_indptr": w.indptr.astype(np.int64),
            "w_indices": w.indices.astype(np.int64),
            "w_data": w.data.astype(np.float32),
        }
        return {prefix + k: v for k, v in arrays.items()}

    @classmethod
    def from_arrays(
        cls, arrays: dict[str, np.ndarray], params: LocalViewParams = LocalViewParams(), prefix: str = ""
    ) -> "LocalViewCells":
        """Rebuild from :meth:`to_arrays` output.

        Raises
        ------
        CorruptFileError
            A field is missing or inconsistent.
        """
        state = {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)}
        try:
            lv = cls(tuple(int(n) for n in state["shape"]), params)
            n = len(state["decay"])
            locations = np.asarray(state["locations"])
            rows = locations.reshape(n, -1) if n else locations.reshape(0, 0)  # no view yet: reshape(0, -1) is ambiguous
            lv._locations = [np.array(r, dtype=np.float64) for r in rows]
            dec = np.array(state["decay"], dtype=np.float64).ravel()
            lv._decay_buf = np.concatenate([dec, np.zeros(max(16, len(dec)))])
            lv._n = len(dec)
            lv._v = np.array(state["v"], dtype=np.float64)
            cur = int(state["current"])
            lv._current = None if cur < 0 else cur
            ip, ix, dv = state["w_indptr"], state["w_indices"], state["w_data"]
            lv._rows = [
                (np.array(ix[ip[i]:ip[i + 1]], dtype=np.int32), np.array(dv[ip[i]:ip[i + 1]], dtype=np.float32))
                for i in range(n)
            ]
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            raise CorruptFileError(f"corrupt local-view state ({exc})", field=prefix + "*") from exc
        if not (len(lv._locations) == len(lv._v) == len(lv._rows) == n):
            raise CorruptFileError("per-view arrays have different lengths", field=prefix + "*")
        size = int(np.prod(lv.shape)) if lv.shape else 0
        for field, values in (("locations", locations), ("decay", dec), ("v", lv._v),
                              ("w_data", np.asarray(state["w_data"], dtype=np.float64))):
            if values.size and not np.isfinite(values).all():  # e.g. -inf written into a saved file
                raise CorruptFileError(f"{field} holds NaN or infinite values", field=prefix + field)
        if any(len(ix) and (ix.min() < 0 or ix.max() >= size) for ix, _ in lv._rows):
            raise CorruptFileError(f"a learnt weight points outside the {lv.shape} grid", field=prefix + "w_indices")
        return lv


def _max_merge(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Element-wise max of two sparse rows given as sorted (indices, values); int32/float32 result."""
    if len(a[0]) == 0:
        return b[0].astype(np.int32), b[1].astype(np.float32)
    idx = np.union1d(a[0], b[0]).astype(np.int32)
    out = np.zeros(len(idx), dtype=np.float32)
    out[np.searchsorted(idx, a[0])] = a[1]
    pos = np.searchsorted(idx, b[0])
    out[pos] = np.maximum(out[pos], b[1])
    return idx, out
