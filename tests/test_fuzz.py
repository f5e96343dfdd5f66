"""Property-based fuzzing of the public entry points: malformed, degenerate, boundary and huge inputs.

Every call either succeeds with finite outputs or raises one of the project's typed errors
(``cansim.CansimError``) with the object's state unchanged, and no call takes longer than a
bound. About 10,000 cases in CI's budget; ``CANSIM_FUZZ_EXAMPLES=N`` runs N per test
(the ``fuzz`` marker selects this file for a longer run: ``pytest -m fuzz``).

The explicit regression tests pin one example of each class of failure found before
(issue 17): hangs on huge finite inputs, state corrupted after an error, silent NaN/inf,
foreign exceptions from corrupt files or degenerate arguments.
"""

from __future__ import annotations

import math
import os
import time
import warnings
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cansim import AttractorParams, Axis, CansimError, Population, RatSLAM, RatSLAMConfig
from cansim.frontends.ids import IdsFrontEnd
from cansim.frontends.panoramic import HeadingOffset
from cansim.frontends.tactile import TactileTemplates
from cansim.frontends.whisk import WhiskFrontEnd
from cansim.local_view import LocalViewCells, LocalViewParams
from cansim.models.posecell_network import PosecellNetwork
from cansim.models.whisker_ratslam import WhiskerRatSLAM
from maps.experience_map import ExperienceMap
from maps.odometry import PlanarOdometry, SpatialOdometry
from whisker_io.features.pfh import chi_squared
from whisker_io.features.sda import nmse
from whisker_io.pose import Pose

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]  # long: CI runs it after the fast loop

N = int(os.environ.get("CANSIM_FUZZ_EXAMPLES", "500"))
SETTINGS = dict(max_examples=N, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
BOUND_S = 5.0



@pytest.fixture(scope="module", autouse=True)
def _compiled_kernels():
    """Compile (or load) the numba kernels the fuzzed calls reach, outside the time bound.

    The bound is there to catch work that grows with a huge input; a first numba
    compilation on a loaded machine can take longer than it and says nothing about that.
    """
    for pop in (Population.openratslam(9, 12, 0.1, backend="numba"), Population.head_direction(36, backend="numba")):
        pop.inject([3] * pop.ndim, 0.1)
        pop.step(velocity=0.3, omega=0.1 if pop.ndim > 1 else None, dt=1.0)
        pop.shift([0.5] * pop.ndim)
    PosecellNetwork(9, 12, 0.5).step(0.2, 0.1, 1.0)  # the C++-parity engine's own kernels
    yield


# numbers a user or a corrupt sensor might hand over
weird_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e17, -1e17, 1e300, -1e300, 1.7976931348623157e308, 2.0**63]),
    st.floats(-10, 10),
)
weird_scalars = st.one_of(weird_floats, st.integers(-(2**70), 2**70), st.booleans(), st.none(), st.text(max_size=3))


def weird_arrays(max_len: int = 8):
    return st.one_of(
        st.lists(weird_floats, min_size=0, max_size=max_len).map(np.array),
        st.lists(st.floats(-5, 5), min_size=0, max_size=max_len).map(np.array),
        weird_scalars,
        st.lists(st.lists(st.floats(-1, 1), min_size=2, max_size=2), min_size=1, max_size=3).map(np.array),
    )


def _finite(out) -> bool:
    if out is None or isinstance(out, (bool, int, str)):
        return True
    if isinstance(out, float):
        return math.isfinite(out) or math.isinf(out)  # inf is a documented answer of nmse
    if isinstance(out, np.ndarray) and out.dtype.kind == "f":
        return not np.isnan(out).any()
    if isinstance(out, tuple):
        return all(_finite(o) for o in out)
    return True


def guarded(snapshot, call):
    """Run ``call``: a typed error must leave ``snapshot()`` unchanged; success must be finite and quick."""
    before = snapshot()
    t0 = time.perf_counter()
    try:
        out = call()
    except CansimError:
        assert snapshot() == before, "state changed by a call that raised"
        return None
    finally:
        assert time.perf_counter() - t0 < BOUND_S, "call took too long"
    assert _finite(out), f"non-finite output {out!r}"
    return out


# ------------------------------------------------------------ the CAN engine
@settings(**SETTINGS)
@given(st.sampled_from(["numpy", "numba"]), weird_arrays(3), weird_arrays(3), weird_scalars)
def test_population_step(backend, velocity, omega, dt):
    pop = Population.openratslam(9, 12, 0.1, backend=backend)
    out = guarded(lambda: pop.activity.tobytes(), lambda: pop.step(velocity=velocity, omega=omega, dt=dt))
    if out is not None:
        assert np.isfinite(pop.activity).all() and pop.activity.min() >= 0


@settings(**SETTINGS)
@given(st.sampled_from(["numpy", "numba"]), weird_arrays(2), weird_scalars)
def test_population_inject_and_shift(backend, index, energy):
    pop = Population.head_direction(36, backend=backend)
    guarded(lambda: pop.activity.tobytes(), lambda: pop.inject(index if np.size(index) else [3], energy))
    guarded(lambda: pop.activity.tobytes(), lambda: pop.shift(np.atleast_1d(np.asarray(energy, dtype=object))[:1]))
    assert np.isfinite(pop.activity).all()


@settings(**SETTINGS)
@given(weird_scalars, weird_scalars)
@example(10**400, 1.0)  # 2 pi / size: OverflowError
@example(3, "a")  # Axis(): math.isfinite("a") was a TypeError
@example(3, 10**400)
def test_axis_constructors(size, step):
    for make in (lambda: Axis.angle("a", size), lambda: Axis.linear("x", size, step), lambda: Axis("a", size, step)):
        guarded(lambda: 0, make)


def _small(x):
    """``x`` with ints above 64 replaced by 9: a grid that large is valid but does not fit in memory."""
    return 9 if isinstance(x, int) and not isinstance(x, bool) and x > 64 else x


def _stepped(params):
    """The activity of a 12-cell ring of ``params`` after one step (NaN if the kernels are NaN)."""
    pop = Population((Axis.angle("a", 12),), params, backend="numpy")
    pop.step(velocity=0.1, dt=1.0)
    return pop.activity


#: constructors of the engine's parts, each taking the fuzzed value for one argument, and the kind it accepts
CONSTRUCTORS = {
    **{f"LocalViewParams.{name}": ((lambda name: lambda x: LocalViewParams(**{name: x}))(name), kind)
       for name, kind in (("inject_energy", float), ("active_decay", float), ("decay_restore", float), ("decay_floor", float),
                          ("recent_exclusion", int), ("learning_rate", float),
                          ("trace_decay", float), ("min_weight", float), ("cpp_unsigned_recent", bool))},
    **{f"AttractorParams.{name}": ((lambda name: lambda x: _stepped(AttractorParams(**{name: x})))(name), kind)
       for name, kind in (("exc_width", "whole"), ("inh_width", "whole"), ("exc_sigma", float), ("inh_sigma", float),
                          ("global_inhibition", float))},
    "IdsFrontEnd.ndim": (lambda x: IdsFrontEnd(x), int),
    "IdsFrontEnd.heading_axis": (lambda x: IdsFrontEnd(3, heading_axis=x), int),
    "IdsFrontEnd.heading_cells": (lambda x: IdsFrontEnd(3, 2, x), int),
    "HeadingOffset.heading_cells": (lambda x: HeadingOffset(TactileTemplates(), 3, 2, x), int),
    "HeadingOffset.heading_axis": (lambda x: HeadingOffset(TactileTemplates(), 3, x, 36), int),
    "PosecellNetwork.dim_xy": (lambda x: PosecellNetwork(_small(x), 12, 0.1), int),
    "PosecellNetwork.dim_th": (lambda x: PosecellNetwork(9, _small(x), 0.1), int),
    "PosecellNetwork.cell_size": (lambda x: PosecellNetwork(9, 12, x), float),
    "PosecellNetwork.decode_window": (lambda x: PosecellNetwork(9, 12, 0.1, decode_window=_small(x)), int),
}


@settings(**{**SETTINGS, "max_examples": max(1, N // 2)})
@given(st.sampled_from(sorted(CONSTRUCTORS)), weird_scalars)
@example("LocalViewParams.recent_exclusion", math.inf)  # int(inf): OverflowError
@example("LocalViewParams.recent_exclusion", 2.5)  # silently truncated to 2
@example("LocalViewParams.inject_energy", "a")  # math.isfinite("a"): TypeError
@example("LocalViewParams.active_decay", 10**400)  # OverflowError
@example("AttractorParams.exc_width", math.inf)  # int(inf): OverflowError
@example("AttractorParams.exc_width", 7.5)  # silently truncated to 7
@example("AttractorParams.exc_width", 10**17 + 1)  # 1e17 taps: MemoryError
@example("AttractorParams.inh_width", 376717)  # a 16-s step (--hypothesis-seed=110, 4x examples)
@example("AttractorParams.inh_sigma", 10**400)  # OverflowError
@example("AttractorParams.exc_sigma", 1e-300)  # sigma^2 underflows: a NaN kernel (RuntimeWarning), NaN activity
@example("AttractorParams.global_inhibition", "a")  # math.isfinite("a"): TypeError
@example("IdsFrontEnd.ndim", math.inf)  # int(inf): OverflowError
@example("IdsFrontEnd.heading_cells", "a")  # int("a"): ValueError
@example("IdsFrontEnd.heading_axis", "a")  # accepted, failed later
@example("HeadingOffset.heading_cells", 2.5)  # silently truncated
@example("PosecellNetwork.decode_window", math.inf)  # int(inf): OverflowError
@example("PosecellNetwork.dim_xy", "a")  # ValueError
@example("PosecellNetwork.cell_size", "a")  # TypeError
def test_part_constructors_refuse_bad_numbers_with_typed_errors(name, x):
    make, kind = CONSTRUCTORS[name]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # numpy's overflow/invalid warnings flag a NaN in the making
        if guarded(lambda: 0, lambda: make(x)) is None:
            return
    if name in ("LocalViewParams.decay_floor", "IdsFrontEnd.heading_axis") and x is None:  # None: no floor, no heading
        return
    # accepted: a value of the argument's kind (no bool for a number, no 2.5 for a count, no NaN/inf, no text)
    if kind is bool:
        assert isinstance(x, bool)
    elif kind is int:
        assert isinstance(x, int) and not isinstance(x, bool)
    elif kind == "whole":  # a count: 7 or 7.0
        assert not isinstance(x, bool) and (isinstance(x, int) or (isinstance(x, float) and x.is_integer()))
    else:
        assert isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


# ------------------------------------------------------------------ models
def ratslam_snapshot(slam):
    em = slam.experience_map
    return (slam.pose_cells.activity.tobytes(), slam.iteration, slam.n_views, em.poses.tobytes(), em.n_links,
            em.accumulator, slam.local_view.decay.tobytes())


@settings(**SETTINGS)
@given(weird_scalars, weird_scalars, weird_scalars, st.one_of(weird_scalars, st.tuples(st.integers(-5, 2**64), weird_floats)))
def test_ratslam_step(vtrans, vrot, dt, observation):
    slam = RatSLAM(RatSLAMConfig(xy_cells=9, heading_cells=12, cell_size_m=0.1))
    slam.step(0.05, 0.1, 1.0, 0)
    guarded(lambda: ratslam_snapshot(slam), lambda: slam.step(vtrans, vrot, dt, observation))
    slam.step(0.05, 0.1, 1.0, 1)  # still usable: a later new view is accepted


@settings(**SETTINGS)
@given(weird_arrays(3), weird_arrays(3), weird_scalars,
       st.one_of(st.none(), st.tuples(weird_arrays(81), weird_arrays(18)), weird_scalars))
def test_whisker_ratslam_step(v, w, dt, observation):
    slam = WhiskerRatSLAM(backend="numpy")
    rng = np.random.default_rng(0)
    slam.step(SpatialOdometry([0.05, 0, 0], [0, 0, 0.2], 1.0), (rng.dirichlet(np.ones(81)), rng.normal(size=18)))

    def snap():
        return (slam.pose_cells.activity.tobytes(), slam.iteration, slam.n_views, slam.object_map.poses.tobytes(),
                len(slam.object_map.history), slam.local_view.decay.tobytes())

    guarded(snap, lambda: slam.step(v, w, dt, observation))


@settings(**SETTINGS)
@given(weird_scalars, weird_scalars, weird_scalars)
def test_posecell_network_step(v, w, dt):
    pc = PosecellNetwork(9, 12, 0.5)
    guarded(lambda: (pc.activity.tobytes(), tuple(pc.decode())), lambda: pc.step(v, w, dt))


# -------------------------------------------------------- maps and odometry
@settings(**SETTINGS)
@given(weird_scalars, weird_scalars, weird_scalars, weird_arrays(3), weird_scalars)
def test_experience_map_on_odo_and_update(v, w, dt, best, view):
    em = ExperienceMap()
    em.update((1.0, 2.0, 3.0), 0, 0)
    snap = lambda: (em.accumulator, em.accum_time_s, em.poses.tobytes(), em.n_links, em.current_id)  # noqa: E731
    guarded(snap, lambda: em.on_odo(v, w, dt))
    guarded(snap, lambda: em.update(best, view, 0))


@settings(**SETTINGS)
@given(weird_arrays(3), weird_arrays(3), weird_scalars)
def test_odometry_types(v, w, dt):
    guarded(lambda: 0, lambda: SpatialOdometry(v, w, dt))
    guarded(lambda: 0, lambda: PlanarOdometry(np.asarray(v).ravel()[0] if np.size(v) else v, w if np.ndim(w) == 0 else 0.0, dt))


# --------------------------------------------------------------- front ends
@settings(**SETTINGS)
@given(st.one_of(weird_scalars, st.tuples(weird_scalars, weird_scalars), st.tuples(st.integers(0, 9), weird_arrays(4))))
def test_ids_front_end(observation):
    fe = IdsFrontEnd(3, heading_axis=2, heading_cells=36)
    fe.match(7)
    guarded(lambda: fe.to_arrays("x")["xids_map"].tobytes(), lambda: fe.match(observation))


@settings(**SETTINGS)
@given(st.one_of(weird_arrays(18), st.lists(st.lists(st.integers(-300, 300), min_size=6, max_size=6), min_size=3, max_size=3).map(np.array)))
def test_tactile_front_end(image):
    fe = TactileTemplates()
    fe.match(np.zeros((3, 6), dtype=np.uint8))
    guarded(lambda: fe.store.data.tobytes(), lambda: fe.match(image))


@settings(**SETTINGS)
@given(weird_arrays(81), weird_arrays(18), st.one_of(st.none(), weird_arrays(18)))
def test_whisk_front_end(pfh, sda, mask):
    fe = WhiskFrontEnd()
    fe.match((np.full(81, 1 / 81), np.zeros(18)))
    obs = (pfh, sda) if mask is None else (pfh, sda, mask)
    guarded(lambda: (fe.pfh.tobytes(), fe.sda.tobytes()), lambda: fe.match(obs))


@settings(**SETTINGS)
@given(weird_scalars, weird_arrays(3), weird_arrays(3))
def test_local_view_observe(view_id, decoded, offset):
    lv = LocalViewCells((5, 5, 5), LocalViewParams())
    lv.observe(0, (1.0, 1.0, 1.0))
    snap = lambda: (lv.n_views, lv.decay.tobytes(), lv.locations.tobytes(), lv.activity.tobytes())  # noqa: E731
    guarded(snap, lambda: lv.observe(view_id, decoded, offset_cells=offset if np.size(offset) == 3 else None))


# ----------------------------------------------------------- sensor features
@settings(**SETTINGS)
@given(weird_arrays(6), weird_arrays(6), weird_arrays(6))
def test_distances(q, v, m):
    guarded(lambda: 0, lambda: chi_squared(q, v))
    guarded(lambda: 0, lambda: nmse(q, v, None, m if np.ndim(m) == 1 and np.size(m) == np.size(v) else None))


@settings(**SETTINGS)
@given(weird_arrays(3), weird_arrays(4))
def test_pose(position, quaternion):
    p = guarded(lambda: 0, lambda: Pose(position, quaternion))
    if p is not None:
        assert abs(np.linalg.norm(p.quaternion_xyzw) - 1.0) < 1e-9 and np.isfinite(p.matrix).all()


# -------------------------------------------------------- corrupt save files
@settings(**SETTINGS)
@given(st.binary(max_size=400), st.integers(0, 10_000))
def test_loading_random_or_truncated_bytes_is_a_typed_error(tmp_path_factory, junk, cut):
    d = tmp_path_factory.mktemp("f")
    good = d / "good.npz"
    slam = RatSLAM(xy_cells=9, heading_cells=12)
    slam.step(0.1, 0.0, 1.0, 0)
    slam.save(good)
    data = good.read_bytes()
    for name, payload in (("junk.npz", junk), ("cut.npz", data[: cut % len(data)]), ("flip.npz", _flip(data, cut))):
        (d / name).write_bytes(payload)
        for loader in (RatSLAM.load, ExperienceMap.load):
            try:
                loader(d / name)
            except CansimError:
                pass


def _flip(data: bytes, at: int) -> bytes:
    b = bytearray(data)
    b[at % len(b)] ^= 0xFF
    return bytes(b)


# ------------------------------------------ issue 17: one regression per class
def test_huge_finite_inputs_do_not_hang():
    t0 = time.perf_counter()
    with pytest.raises(CansimError):
        ExperienceMap().on_odo(0.0, 1.0, 1e17)
    with pytest.raises(CansimError):
        PosecellNetwork().step(0.0, 1e17, 1.0)
    slam = RatSLAM()
    with pytest.raises(CansimError):
        slam.step(0.0, 0.0, 1.0, (5, 6.2e16))
    assert time.perf_counter() - t0 < 2.0


def test_state_is_not_corrupted_by_a_refused_view():
    slam = RatSLAM()
    with pytest.raises(CansimError):
        slam.on_view((5, -1.7976931348623157e308))
    assert slam.n_views == 0
    assert slam.step(0.0, 0.0, 1.0, 5).new_view  # the id was not recorded: a new view now
    with pytest.raises(CansimError):
        slam.step(0.0, 0.0, 1.0, 2**63)
    slam.save(os.devnull if os.name != "nt" else "nul")  # saving still works


def test_no_silent_nan_or_inf():
    with pytest.raises(CansimError):
        RatSLAM().on_odo(1e300, 0, 1.0)
    ring = Population.head_direction(36, backend="numba")
    with pytest.raises(CansimError):
        ring.shift([9.16e253])
    with pytest.raises(CansimError):
        ring.inject([3], 1e308)
    assert np.isfinite(ring.activity).all()
    assert nmse([1e200], [0.0]) == pytest.approx(1.0)


def test_no_foreign_exceptions(tmp_path):
    (tmp_path / "empty.npz").write_bytes(b"")
    slam = RatSLAM()
    slam.step(0.1, 0, 1, 0)
    slam.save(tmp_path / "good.npz")
    data = (tmp_path / "good.npz").read_bytes()
    (tmp_path / "trunc.npz").write_bytes(data[: len(data) // 2])
    for f in ("empty.npz", "trunc.npz"):
        with pytest.raises(CansimError):
            RatSLAM.load(tmp_path / f)
    with pytest.raises(CansimError):
        Axis.angle("t", 0)
    with pytest.raises(CansimError):
        chi_squared(np.array(0), np.ones(3))
    assert not issubclass(zipfile.BadZipFile, CansimError)  # so the loaders must translate it


def test_safety_limits_given_as_tuples_are_refused():
    from whisker_io.hw.safety import SafetyEnvelope

    with pytest.raises(CansimError):
        SafetyEnvelope(max_tool_tilt=(0.5, 0.5, 0.7))
    with pytest.raises(CansimError):
        SafetyEnvelope(max_deflection=(1, 2))
    with pytest.raises(CansimError):
        Pose([0, 0, 0], [0, 0, 1e300, 1])
