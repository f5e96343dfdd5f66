"""OpenRatSLAM's pose-cell network reproduced to the last bit (``PosecellNetwork`` of the C++ core).

:class:`cansim.population.Population` with ``frame="openratslam"`` implements
the same model with separable kernels and its own summation order; it agrees
with the C++ core to ~1e-15 cells, which is not enough for a faithful replay:
OpenRatSLAM truncates decoded coordinates with ``(int)``, and a packet sitting
exactly on a cell decodes to ``9.999999999999998`` in C++, so a view
template remembers cell 9 where a differently rounded sum gives 10. From then
on the two runs differ by fractions of a cell.

This engine performs the C++ arithmetic in the C++ order:

* ``excite``/``inhibit`` scatter every non-zero cell through the full 3-D
  kernel (``pc_w_e_dim``\\ :sup:`3` Gaussian of variance parameter ``pc_w_e_var``,
  normalised by its sequential sum), x outermost, theta innermost;
* global inhibition, then normalisation by the sequential total;
* translation per theta layer: turn the layer by ``floor(2 dir / pi)`` quarter
  turns, shift by the four bilinear weights of the residual angle, wrap the
  overflow, turn back (valid up to one cell per step). Like the C++ (and the
  MATLAB it was ported from) the fold-back skips two overflow cells - the
  +x overflow of row 0 and the +y overflow of column 0 of the turned layer -
  so a packet on those edges loses that share until the next normalisation;
* rotation by the two integer theta shifts around ``|vrot| / (2 pi / n_th)``;
* ``find_best``: maximum cell (first in theta, y, x order), sums over the
  +-``pc_cells_to_avg`` box with the C++ wrap tables (cells repeat when the box
  is wider than the grid, as in C++), population vector with the ``(i + 1)``
  angle tables, ``- 1`` and the ``[0, n]`` wrap loops.

Two shortcuts skip only work whose result is known bit for bit (see
:mod:`cansim.models._posecell_kernels`): the inhibition is gathered, in the
scatter's order per cell, only for cells excited to at least the global
inhibition (the others end at 0 whatever their inhibition), and theta layers
holding only ``+0.0`` are not translated, rotated or searched. Trigonometric
and exponential functions come from Python's :mod:`math`, i.e. the C library,
as in the C++ build. The result equals OpenRatSLAM's on identical
inputs; this was checked against the C++ core driven the way its ROS nodes
drive it (see ``bench/README.md``), and the tests pin each rule on hand-made
cases.

Layout: :attr:`PosecellNetwork.activity` and injection indices use cansim's
``(x, y, theta)`` C-order like :class:`~cansim.population.Population`; the
engine stores ``[theta, y, x]`` internally as the C++ does.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from cansim._renamed import renamed_keywords
from cansim.errors import ConfigError, InvalidInputError, ShapeError, ZeroActivityError
from cansim.params import AttractorParams
from whisker_io.validation import config_field
from cansim.grid_inputs import checked_injection
from whisker_io.validation import MAX_STEP_M, MAX_TURN_RAD

__all__ = ["PosecellNetwork"]


def _wrap_table(n: int, half: int) -> np.ndarray:
    """C++ ``generate_wrap``: ``[n-half .. n-1, 0 .. n-1, 0 .. half-1]``."""
    return np.concatenate([np.arange(n - half, n), np.arange(n), np.arange(half)]).astype(np.int64)


def _gather_table(n: int, dim: int, src_stride: int, w_stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Each target coordinate's ``dim`` sources on one axis, in the C++ scatter's order (ascending).

    The scatter sends source ``s`` to target ``(s + d - dim // 2) mod n`` with kernel offset
    ``d``; for target ``t`` the sources are ``(t + dim // 2 - d) mod n``. Returns, shape
    ``(n, dim)`` uint64 each, the sources sorted ascending times ``src_stride`` and their
    offsets ``d`` times ``w_stride``. Needs ``n >= dim`` (distinct sources).
    """
    half = dim // 2
    src = np.empty((n, dim), dtype=np.uint64)
    off = np.empty((n, dim), dtype=np.uint64)
    for t in range(n):
        pairs = sorted(((t + half - d) % n, d) for d in range(dim))
        src[t] = [s * src_stride for s, _ in pairs]
        off[t] = [d * w_stride for _, d in pairs]
    return src, off


def _kernel_weights(dim: int, var: float) -> np.ndarray:
    """C++ ``norm2d`` over a ``dim``^3 cube (k, j, i order), divided by its sequential sum."""
    c = dim // 2
    w = []
    total = 0.0
    scale = 1.0 / (var * math.sqrt(2.0 * math.pi))
    for k in range(dim):
        for j in range(dim):
            for i in range(dim):
                num = -(i - c) * (i - c) - (j - c) * (j - c) - (k - c) * (k - c)  # integer, as in C++
                v = scale * math.exp(num / (2.0 * var * var))
                w.append(v)
                total += v
    return np.array([v / total for v in w])


class PosecellNetwork:
    """OpenRatSLAM's 3-D pose cells with the C++ core's exact arithmetic.

    Parameters
    ----------
    xy_cells, heading_cells : int
        Cells on the x and y axes (21) and on the heading axis (36): OpenRatSLAM's
        ``pc_dim_xy`` and ``pc_dim_th``, under
        :class:`~cansim.models.ratslam_config.RatSLAMConfig`'s names (0.1's ``dim_xy``
        and ``dim_th`` still work until 0.3, with a DeprecationWarning).
    cell_size_m : float
        Metres per cell (> 0): ``pc_cell_x_size`` (0.1's ``cell_size``, likewise).
    params : AttractorParams
        Kernels and global inhibition, one scalar per field (the C++ grid is
        isotropic): ``exc_width`` / ``inh_width`` odd widths in cells (OpenRatSLAM
        ``pc_w_e_dim`` 7, ``pc_w_i_dim`` 5); ``exc_sigma`` / ``inh_sigma`` the C++
        ``pc_w_e_var`` (1) and ``pc_w_i_var`` (2), used as sigma and integers in
        OpenRatSLAM (its fields are ``int``), so a non-integral value is rejected;
        ``global_inhibition`` (``pc_global_inhib``, 2e-5). The kernels are always
        normalised to sum 1, as the C++ does.
    decode_window : int
        ``find_best``'s half window (3 in the C++, not configurable there).

    Notes
    -----
    Starts like the C++: one cell of energy 1 at ``(xy_cells // 2, xy_cells // 2,
    heading_cells // 2)`` and the best estimate at those integer coordinates (not
    decoded). Float64 only; one process-wide numba compile (cached on disk).

    Examples
    --------
    >>> pc = PosecellNetwork()
    >>> best = pc.step(0.0, 0.0, 1.0)   # a lone cell decodes just below its index, as in C++
    >>> float(best[0]), int(best[0])
    (9.999999999999998, 9)
    """

    @renamed_keywords(dim_xy="xy_cells", dim_th="heading_cells", cell_size="cell_size_m")
    def __init__(
        self,
        xy_cells: int = 21,
        heading_cells: int = 36,
        cell_size_m: float = 1.0,
        *,
        params: AttractorParams = AttractorParams(),
        decode_window: int = 3,
    ) -> None:
        def scalar(name: str) -> float:
            value = getattr(params, name)
            if isinstance(value, (list, tuple, np.ndarray)):
                raise ConfigError(f"{name} must be one number in the OpenRatSLAM engine (an isotropic grid), got {value!r}")
            return value

        w_e_dim, w_i_dim = scalar("exc_width"), scalar("inh_width")
        w_e_var, w_i_var = scalar("exc_sigma"), scalar("inh_sigma")
        for name, v in (("xy_cells", xy_cells), ("heading_cells", heading_cells)):
            config_field(v, name, int, minimum=1)
        config_field(decode_window, "decode_window", int, minimum=0)
        config_field(cell_size_m, "cell_size_m", float, above=0, hint="give metres per cell")
        global_inhib, cells_to_avg = float(params.global_inhibition), int(decode_window)
        if params.kernel_normalisation != "sum":
            raise ConfigError("kernel_normalisation must be 'sum' in the OpenRatSLAM engine (the C++ kernels sum to 1)")
        for name, v in (("exc_sigma", w_e_var), ("inh_sigma", w_i_var)):
            if float(v) != int(v) or v <= 0:
                raise ConfigError(f"{name} must be a positive integer in the OpenRatSLAM engine (a C++ int), got {v!r}")
        for name, v in (("exc_width", w_e_dim), ("inh_width", w_i_dim)):
            if int(v) < 1 or int(v) % 2 == 0:
                raise ConfigError(f"{name} must be a positive odd integer, got {v!r}")
        half_max = max(w_e_dim // 2, w_i_dim // 2, cells_to_avg)
        if min(xy_cells, heading_cells) < half_max:
            raise ConfigError(
                f"xy_cells and heading_cells must be >= {half_max} (the widest kernel half-width / "
                f"find_best window), got {xy_cells} and {heading_cells}"
            )
        self._nxy, self._nth = int(xy_cells), int(heading_cells)
        self._cell = float(cell_size_m)
        self._gi = float(global_inhib)
        self._half = int(cells_to_avg)
        self._e_dim, self._i_dim = int(w_e_dim), int(w_i_dim)
        self._w_exc = _kernel_weights(self._e_dim, float(int(w_e_var)))
        self._w_inh = _kernel_weights(self._i_dim, float(int(w_i_var)))
        n, m = self._nxy, self._nth
        self._e_xy, self._e_th = _wrap_table(n, self._e_dim // 2), _wrap_table(m, self._e_dim // 2)
        self._i_xy, self._i_th = _wrap_table(n, self._i_dim // 2), _wrap_table(m, self._i_dim // 2)
        self._a_xy, self._a_th = _wrap_table(n, self._half), _wrap_table(m, self._half)
        d = self._i_dim
        # the inhibition is gathered (only where it matters) when each source reaches a target once
        self._gather = (
            (*_gather_table(n, d, 1, 1), *_gather_table(n, d, n, d), *_gather_table(m, d, n * n, d * d))
            if d in (1, 3, 5, 7, 9) and min(n, m) >= d and self._w_inh.min() >= 0.0 else None
        )
        self._sin_xy = np.array([math.sin((i + 1) * 2.0 * math.pi / n) for i in range(n)])
        self._cos_xy = np.array([math.cos((i + 1) * 2.0 * math.pi / n) for i in range(n)])
        self._sin_th = np.array([math.sin((i + 1) * 2.0 * math.pi / m) for i in range(m)])
        self._cos_th = np.array([math.cos((i + 1) * 2.0 * math.pi / m) for i in range(m)])
        self._c_size_th = (2.0 * math.pi) / m
        self._layer_tables = {add: self._layers(add) for add in (0.0, math.pi)}
        self._p = np.zeros((m, n, n))
        self._tmp = np.empty_like(self._p)
        self._spare = np.empty_like(self._p)  # the next state is computed here; the two swap after a step
        self._best = np.array([math.floor(n / 2.0), math.floor(n / 2.0), math.floor(m / 2.0)])
        self._p[int(self._best[2]), int(self._best[1]), int(self._best[0])] = 1.0
        # theta layers of self._p that may hold a non-zero cell (False: only +0.0); the kernels
        # skip the others. Conservative: a True layer may be all zeros.
        self._live = np.zeros(m, dtype=np.bool_)
        self._live[int(self._best[2])] = True
        self._live_spare = self._live.copy()
        self._k: object = None

    def _layers(self, angle_to_add: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Quarter turns and residual-angle cos/sin of every theta layer (C++ ``path_integration``)."""
        rot, cs, sn = [], [], []
        for k in range(self._nth):
            direction = k * self._c_size_th + angle_to_add
            q = math.floor(direction * 2 / math.pi)
            dir90 = direction - q * math.pi / 2
            rot.append(q % 4)
            cs.append(math.cos(dir90))
            sn.append(math.sin(dir90))
        return np.array(rot, dtype=np.int64), np.array(cs), np.array(sn)

    @property
    def _kernels(self):  # noqa: ANN202 - module object
        if self._k is None:
            from cansim.models import _posecell_kernels

            self._k = _posecell_kernels
        return self._k

    # ------------------------------------------------------------------ views
    @property
    def shape(self) -> tuple[int, int, int]:
        """``(xy_cells, xy_cells, heading_cells)``: cansim's (x, y, theta) axis order."""
        return (self._nxy, self._nxy, self._nth)

    @property
    def size(self) -> int:
        """Number of cells."""
        return self._nxy * self._nxy * self._nth

    @property
    def dtype(self) -> np.dtype:
        """Always float64 (the C++ ``Posecell`` is ``double``)."""
        return np.dtype(np.float64)

    @property
    def activity(self) -> np.ndarray:
        """A copy of the activity, shape :attr:`shape` (x, y, theta)."""
        return np.ascontiguousarray(self._p.transpose(2, 1, 0))

    @activity.setter
    def activity(self, value: np.ndarray) -> None:
        arr = np.asarray(value)
        if arr.shape != self.shape:
            raise ShapeError(f"activity must have shape {self.shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)) or np.any(arr < 0):
            raise InvalidInputError("activity must be finite and >= 0")
        self._p = np.ascontiguousarray(arr.transpose(2, 1, 0), dtype=np.float64)
        self._tmp = np.empty_like(self._p)
        self._spare = np.empty_like(self._p)
        self._live = np.ones(self._nth, dtype=np.bool_)  # a given activity may hold -0.0: no layer is skipped
        self._live_spare = self._live.copy()

    @property
    def best(self) -> np.ndarray:
        """Last ``find_best`` result (x, y, theta) in fractional cells, each in ``[0, n]``."""
        return self._best.copy()

    @best.setter
    def best(self, value: np.ndarray) -> None:
        b = np.asarray(value, dtype=np.float64)
        if b.shape != (3,) or not np.all(np.isfinite(b)):
            raise InvalidInputError(f"best must be 3 finite numbers, got {value!r}")
        self._best = b.copy()

    def decode(self) -> np.ndarray:
        """The last ``find_best`` estimate (the initial integer centre before the first step)."""
        return self._best.copy()

    # ------------------------------------------------------------------ steps
    def _injection_cells(self, injection: Optional[tuple[np.ndarray, np.ndarray]]) -> list[tuple[int, int, int, float]]:
        """Validated injection as (x, y, theta, energy) per entry, in order."""
        if injection is None:
            return []
        fi, vals = checked_injection(*injection, self.size)
        ny, nth = self._nxy, self._nth
        out = []
        for flat, v in zip(fi.tolist(), vals.tolist()):  # (x, y, theta) C-order, as np.unravel_index
            xy, t = divmod(flat, nth)
            x, y = divmod(xy, ny)
            out.append((x, y, t, v))
        return out

    def step(
        self,
        vtrans: float,
        vrot: float,
        dt: float,
        *,
        injection: Optional[tuple[np.ndarray, np.ndarray]] = None,
    ) -> np.ndarray:
        """Injection, then C++ ``on_odo``: dynamics, path integration, ``find_best``.

        Parameters
        ----------
        vtrans : float
            Forward speed, m/s (negative: backwards, C++ adds pi to every direction).
        vrot : float
            Yaw rate, rad/s.
        dt : float
            Seconds; the step moves ``vtrans * dt / cell_size_m`` cells (<= 1 for
            meaningful results, as in C++) and ``vrot * dt`` rad.
        injection : (flat_index, values), optional
            View energy added cell by cell, in order, before the dynamics
            (``on_view_template``'s ``inject``); indices in (x, y, theta) C-order.

        Returns
        -------
        ndarray, shape (3,)
            ``find_best``'s (x, y, theta) in fractional cells.

        Raises
        ------
        InvalidInputError, ShapeError
            Non-finite odometry or a malformed injection; nothing changed.
        ZeroActivityError
            Global inhibition silenced every cell (the C++ asserts); nothing changed.
        """
        try:
            v, w, t = float(vtrans), float(vrot), float(dt)
        except (TypeError, ValueError):
            raise InvalidInputError(f"odometry must be real numbers, got {vtrans!r}, {vrot!r}, {dt!r}") from None
        if not (math.isfinite(v) and math.isfinite(w) and math.isfinite(t)):
            raise InvalidInputError(f"odometry must be finite, got vtrans={v!r}, vrot={w!r}, dt={t!r}")
        if abs(w * t) > MAX_TURN_RAD or abs(v * t) > MAX_STEP_M:
            raise InvalidInputError(
                f"odometry step of {v * t:g} m / {w * t:g} rad exceeds {MAX_STEP_M:g} m / {MAX_TURN_RAD:g} rad; "
                "the sample is corrupt or must be split"
            )
        return self._step_validated(v, w, t, injection=injection)

    def _step_validated(
        self, vtrans: float, vrot: float, dt: float, *, injection: Optional[tuple[np.ndarray, np.ndarray]] = None
    ) -> np.ndarray:
        """:meth:`step` for odometry checked already (:class:`maps.odometry.PlanarOdometry`:
        finite, within the step bounds) - the path of :class:`cansim.models.slam_loop.SlamLoop`,
        so a sample is validated once. The injection is still checked."""
        v, w, t = float(vtrans), float(vrot), float(dt)
        cells = self._injection_cells(injection)
        kern = self._kernels
        p = self._spare  # the next state; a step that raises leaves self._p (and self._live) as they were
        live = self._live_spare
        live[:] = self._live
        if self._gather is not None:
            src = self._p  # read, not written: the injection is added here and undone on failure
            undo = [(x, y, th, src[th, y, x]) for x, y, th, _ in cells]
            for x, y, th, e in cells:
                src[th, y, x] += e
                live[th] = True
            total = kern.dynamics_gather(
                src, p, self._tmp, self._w_exc, self._e_dim, self._e_xy, self._e_th, self._w_inh, self._i_dim,
                self._i_xy, self._i_th, *self._gather, self._gi, live
            )
            for x, y, th, old in reversed(undo):  # the old values (bits), in reverse for repeated cells
                src[th, y, x] = old
        else:
            np.copyto(p, self._p)
            for x, y, th, e in cells:
                p[th, y, x] += e
            total = kern.dynamics(
                p, self._tmp, self._w_exc, self._e_dim, self._e_xy, self._e_th, self._w_inh, self._i_dim, self._i_xy,
                self._i_th, self._gi
            )
            live[:] = True
        if not total > 0.0:
            raise ZeroActivityError(
                "global inhibition silenced every pose cell (OpenRatSLAM would abort); state left unchanged - "
                "lower attractor.global_inhibition or inject energy"
            )
        v, w = v * t, w * t
        v /= self._cell
        add = 0.0
        if v < 0:
            v, add = -v, math.pi
        rot, cs, sn = self._layer_tables[add]
        kern.translate(p, rot, cs, sn, v, live)
        if w != 0:
            weight = abs(w) / self._c_size_th
            while weight > 1:
                weight -= 1
            if weight == 0:
                weight = 1.0
            sign = -1.0 if w < 0 else 1.0
            s1 = int(sign * math.floor(abs(w) / self._c_size_th))
            s2 = int(sign * math.ceil(abs(w) / self._c_size_th))
            while s1 > 0:
                s1 -= self._nth
            while s2 > 0:
                s2 -= self._nth
            kern.rotate_theta(p, self._tmp, s1, s2, weight, live)
        sums = kern.best_sums(
            p, self._half, self._a_xy, self._a_th, self._sin_xy, self._cos_xy, self._sin_th, self._cos_th, live
        )
        self._p, self._spare = p, self._p
        self._live, self._live_spare = live, self._live
        self._best = np.array([
            self._wrap(math.atan2(sums[0], sums[1]) * self._nxy / (2.0 * math.pi) - 1.0, self._nxy),
            self._wrap(math.atan2(sums[2], sums[3]) * self._nxy / (2.0 * math.pi) - 1.0, self._nxy),
            self._wrap(math.atan2(sums[4], sums[5]) * self._nth / (2.0 * math.pi) - 1.0, self._nth),
        ])
        return self._best.copy()

    @staticmethod
    def _wrap(value: float, n: int) -> float:
        """C++ ``find_best``'s wrap loops: into ``[0, n]`` (n itself is kept)."""
        while value < 0:
            value += n
        while value > n:
            value -= n
        return value

    def __repr__(self) -> str:
        return f"PosecellNetwork(x={self._nxy}, y={self._nxy}, theta={self._nth}, cell_size_m={self._cell})"
