"""Identification cost per whisk against a library (issue 22 item 5: <= 2 ms at 50 objects).

``maps.surface_match.SurfaceMatcher.step``: one whisk of 8 contacts weighed by every
library object's particle filter (K objects x 1,500 stored points, about 100 experiences
of 15 contacts each, 200 hypotheses per object), K = 12, 25, 50 distinct objects
(ellipsoids of seeded sizes); the library is built once per K (not timed).

* ``steady``: after 30 whisks on object 0 (the window is full and objects whose evidence
  fell ``prune_margin`` below the best are dropped), the cost of one more whisk: what a
  presentation pays per whisk once the library has been narrowed down.
* ``all_active``: the same with pruning off (``prune_margin`` huge): every object's filter
  runs, the cost of the first ``window_whisks`` whisks of a presentation.
* ``presentation``: a whole presentation of object 0, timed as one call: 60 whisks from
  poses on a loop round it (17 per turn, 0.32 m from its centre, the elevation swinging
  +-20 deg, the array's axis on the centre), each whisk up to 8 contacts where rays from
  the end-effector within +-27 deg of its axis meet the ellipsoid (3 mm noise), odometry
  with Eq 6.4-6.11's noise (:func:`whisker_io.sim.odometry_noise.noisy_odometry`), pruning
  on: what a presentation pays on average per whisk (the time / 60), its first
  ``window_whisks`` whisks with every object in question included. Unlike ``steady``,
  whose repeated whisk from one standing pose can be fitted by every look-alike, the
  moving arm lets the filters of objects that do not fit fall behind.
* ``study_library``: the recognition study's own 50-object library (the project's objects and
  procedural shapes, maps built by the study's ``map_job`` on seed 0, as its full mode builds
  them; about half a minute, not timed), its first 12 / 25 / 50 objects, and one presentation
  along B (whole loops, at least 200 whisks, as the study presents) of two project objects, two
  freeform shapes and a novel one, replayed through the study's own
  ``cansim.studies.recognition.surface_targets``: what the study pays per whisk (the time / the
  whisks, ``extra_info``) on real shapes, which prune faster than look-alike ellipsoids.
* ``refine`` 0 / 1: without / with the registration-refined proposal
  (``SurfaceMatchConfig.refine_iterations=1, refine_prior_scale=4``: one Levenberg-Marquardt
  step per hypothesis and whisk).

The kernels share the hypotheses among numba's threads (every core by default;
``NUMBA_NUM_THREADS`` sets it), so the default timer (wall clock) is what a user waits;
``--benchmark-timer=time.process_time`` gives the CPU time of all threads.

Run: ``python -m pytest bench/test_bench_recognition.py --benchmark-only --benchmark-columns=min,median,rounds``
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from scipy.spatial.transform import Rotation

from maps.odometry import SpatialOdometry
from maps.surface_match import SurfaceLibrary, SurfaceMatchConfig, SurfaceMatcher
from whisker_io.pose import Pose
from whisker_io.sim.odometry_noise import noisy_odometry
from whisker_io.sim.trajectories import facing_pose

PRESENTATION_WHISKS = 60


def _ellipsoid_points(rng: np.random.Generator, n: int, axes_m: np.ndarray) -> np.ndarray:
    """``n`` points on an ellipsoid with semi-axes ``axes_m`` standing on z = 0, with 3 mm noise, metres."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return d * axes_m + [0.0, 0.0, axes_m[2]] + rng.normal(0.0, 0.003, (n, 3))


def _library(n_objects: int) -> tuple[SurfaceLibrary, np.ndarray]:
    rng = np.random.default_rng(0)
    axes = np.array([0.1, 0.1, 0.175]) * rng.uniform(0.6, 1.4, (n_objects, 3))
    axes[0] = [0.1, 0.1, 0.175]
    lib = SurfaceLibrary([_ellipsoid_points(rng, 1500, a) for a in axes], [f"object{i}" for i in range(n_objects)])
    return lib, axes


_LIBRARIES: dict[int, tuple[SurfaceLibrary, np.ndarray]] = {}


@pytest.mark.parametrize("refine", [0, 1])
@pytest.mark.parametrize("mode", ["steady", "all_active"])
@pytest.mark.parametrize("n_objects", [12, 25, 50])
def test_surface_matcher_step_per_whisk(benchmark, n_objects, mode, refine):
    if n_objects not in _LIBRARIES:
        _LIBRARIES[n_objects] = _library(n_objects)
    lib, axes = _LIBRARIES[n_objects]
    rng = np.random.default_rng(1)
    cfg = SurfaceMatchConfig(refine_iterations=refine, refine_prior_scale=4.0)
    if mode == "all_active":
        cfg = replace(cfg, prune_margin=1e9)
    start = np.array([0.0, -0.3, 0.175, 0.0, 0.0, 0.0, 1.0])
    matcher = SurfaceMatcher(lib, start, cfg)
    still = SpatialOdometry([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0)
    whisk = _ellipsoid_points(rng, 8, axes[0]) - start[:3]  # 8 contacts of object 0 in the end-effector frame
    for _ in range(30):  # the window fills; pruning (steady) narrows the library
        matcher.step(still, whisk)
    impulses = benchmark(matcher.step, still, whisk)
    assert np.asarray(impulses).shape[-1] == n_objects
    benchmark.extra_info["active_objects"] = int(matcher.active.sum())


def _loop_poses(n: int, centre: np.ndarray, radius_m: float = 0.32) -> list[Pose]:
    """``n`` end-effector poses on a loop round ``centre`` (17 per turn, elevation +-20 deg), facing it (+y)."""
    poses = []
    for i in range(n):
        az, el = 2.0 * np.pi * i / 17.0, np.radians(20.0 * np.sin(2.0 * np.pi * i / 23.0))
        out = np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
        poses.append(facing_pose(centre, -out, radius_m))
    return poses


def _ray_contacts(pose: Pose, axes_m: np.ndarray, centre: np.ndarray, rng: np.random.Generator, k: int = 8) -> np.ndarray | None:
    """Up to ``k`` points (end-effector frame, m) where random rays ahead of ``pose`` meet the ellipsoid (3 mm noise)."""
    rot = Rotation.from_quat(pose.quaternion_xyzw)
    o = (pose.position_m - centre) / axes_m
    found = []
    for _ in range(40):
        d = rot.apply([rng.uniform(-0.5, 0.5), 1.0, rng.uniform(-0.5, 0.5)])
        d /= np.linalg.norm(d)
        dd = d / axes_m
        a, b, c = dd @ dd, 2.0 * o @ dd, o @ o - 1.0
        if b * b - 4.0 * a * c <= 0.0:
            continue
        t = (-b - np.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)
        if 0.0 < t <= 0.45:
            found.append(pose.position_m + t * d + rng.normal(0.0, 0.003, 3))
        if len(found) == k:
            break
    return rot.inv().apply(np.array(found) - pose.position_m) if found else None


@pytest.mark.parametrize("refine", [0, 1])
@pytest.mark.parametrize("n_objects", [12, 25, 50])
def test_surface_matcher_presentation(benchmark, n_objects, refine):
    if n_objects not in _LIBRARIES:
        _LIBRARIES[n_objects] = _library(n_objects)
    lib, axes = _LIBRARIES[n_objects]
    rng = np.random.default_rng(2)
    centre = np.array([0.0, 0.0, axes[0][2]])
    poses = _loop_poses(PRESENTATION_WHISKS, centre)
    whisks = [_ray_contacts(p, axes[0], centre, rng) for p in poses]
    odometry = [None] + [SpatialOdometry(*noisy_odometry(a, b, rng)) for a, b in zip(poses[:-1], poses[1:])]
    cfg = SurfaceMatchConfig(refine_iterations=refine, refine_prior_scale=4.0)
    start = np.r_[poses[0].position_m, poses[0].quaternion_xyzw]
    warm = SurfaceMatcher(lib, start, cfg)  # every kernel (the move's too) compiled outside the timing
    warm.step(None, whisks[0])
    warm.step(odometry[1], whisks[1])

    def present() -> SurfaceMatcher:
        matcher = SurfaceMatcher(lib, start, cfg)
        for odo, pts in zip(odometry, whisks):
            matcher.step(odo, pts)
        return matcher

    matcher = benchmark.pedantic(present, rounds=3, iterations=1)
    assert sum(w is not None for w in whisks) >= PRESENTATION_WHISKS // 2  # the loop touches the object
    benchmark.extra_info["whisks"] = PRESENTATION_WHISKS
    benchmark.extra_info["active_objects_at_end"] = int(matcher.active.sum())


# ------------------------------------------------------------- the recognition study's own library
#: Presented along trajectory B against the study's library: two of the project's objects, two freeform
#: shapes and a novel one (never mapped)
STUDY_PRESENTED = ("mug", "kettle", "duck", "blob", "knot-h0")


@pytest.fixture(scope="module")
def study_library(tmp_path_factory):
    """The recognition study's maps of its 50-object library (seed 0), built by its own ``map_job`` as its
    full mode builds them (thresholds calibrated on seed 0, each object's roll chosen as the study
    chooses it; not timed, about half a minute), and the whisks of a presentation along B of each of
    :data:`STUDY_PRESENTED` (as the study presents: whole loops of its trajectory with the study's
    reach and the object's roll, at least 200 whisks, the ``tip`` contacts at the study's contact
    noise, Eq 6.4-6.11 odometry)."""
    from cansim.studies import recognition as rec
    from whisker_io.sim.catalogue import object_file_names, resolve_object
    from whisker_io.sim.odometry_noise import noisy_odometry as noisy
    from whisker_io.sim.shapes import library_names
    from whisker_io.sim.sweep import ContactNoise
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    out = tmp_path_factory.mktemp("study")
    names = list(library_names(50))
    rolls = tuple(rec.roll_job((n, rec.REACH_CONTACTS)) for n in dict.fromkeys((*names, *STUDY_PRESENTED)))  # as run() does
    setup = rec.Setup(seed=0, map_loops=2, whisks=200, thresholds=rec.calibrated_thresholds("first-seed", (0,), None),
                      out=str(out), matchers=("surface",), rolls_deg=rolls)
    surfaces = [rec.map_job((n, setup, f))["surface"] for n, f in zip(names, object_file_names(names))]
    presentations = {}
    for i, name in enumerate(STUDY_PRESENTED):
        mesh = resolve_object(name).mesh
        loop = object_trajectory(mesh, "B", 1, reach_contacts=rec.REACH_CONTACTS, roll_deg=setup.roll_of(name))
        poses = loop * math.ceil(setup.whisks / len(loop))  # whole loops, at least the study's 200 whisks
        chain = WhiskChain(mesh, signals=False, contact_model=rec.CONTACT_MODEL,
                           contact_noise=ContactNoise().scaled(rec.NOISE_SCALE))
        rng = np.random.default_rng(100 + i)
        contacts = []
        for p in poses:
            pts = getattr(chain.features(p, rng), "contact_points_m", None)
            contacts.append(None if pts is None else np.asarray(pts, dtype=np.float64))
        odometry = [None] + [SpatialOdometry(*noisy(a, b, rng)) for a, b in zip(poses[:-1], poses[1:])]
        presentations[name] = (poses[0], odometry, contacts)
    return names, surfaces, presentations


@pytest.mark.parametrize("presented", STUDY_PRESENTED)
@pytest.mark.parametrize("n_objects", [12, 25, 50])
def test_study_library_presentation(benchmark, study_library, n_objects, presented):
    """One presentation along B through :func:`cansim.studies.recognition.surface_targets` (the study's
    matcher, default settings) against the first ``n_objects`` of the study's library: what the study
    pays per whisk (the time / the whisks) on libraries of real shapes, not look-alike ellipsoids."""
    from cansim.studies import recognition as rec

    names, surfaces, presentations = study_library
    library = rec.load_surface_library(surfaces[:n_objects], names[:n_objects])
    start, odometry, contacts = presentations[presented]
    rec.surface_targets(library, start, odometry[:3], contacts[:3])  # compiled outside the timing
    targets = benchmark.pedantic(rec.surface_targets, args=(library, start, odometry, contacts), rounds=3, iterations=1)
    assert len(targets) == len(contacts)
    benchmark.extra_info["whisks"] = len(contacts)
    benchmark.extra_info["own_impulses"] = int(np.sum(targets == names.index(presented))) if presented in names[:n_objects] else 0
    benchmark.extra_info["other_impulses"] = int(np.sum(targets >= 0)) - benchmark.extra_info["own_impulses"]
