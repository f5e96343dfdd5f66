"""The matchers of the recognition benchmark (cansim.studies.recognition): selection and the surface path.

Fast checks (the study's runs are in the slow ``test_recognition_study.py``): an unknown
matcher is refused before any work, and the surface matcher's per-whisk targets on a
hand-made two-object library go to the object whose stored surface the whisks touch.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import ConfigError, InvalidInputError, ShapeError
from cansim.studies import recognition
from maps.odometry import SpatialOdometry
from whisker_io.pose import Pose


@settings(max_examples=20, deadline=None)
@given(st.one_of(st.just(()), st.lists(st.sampled_from(["thesis", "surface", "Thesis", "", "region", "surface "]),
                                       min_size=1, max_size=3).filter(lambda m: any(x not in recognition.MATCHERS for x in m))))
def test_unknown_matchers_are_refused_before_any_work(tmp_path_factory, matchers) -> None:
    out = tmp_path_factory.mktemp("rec") / "out"
    with pytest.raises(ConfigError):
        recognition.run(out, objects=["mug"], novel=[], matchers=matchers, progress=False)
    assert not out.exists()


_RULES = st.text(max_size=12).filter(lambda r: r not in recognition.CALIBRATIONS)


@settings(max_examples=20, deadline=None)
@given(st.one_of(_RULES, st.sampled_from(["Pooled", "first_seed", "first-seed ", "seed0"])))
def test_unknown_calibration_rules_are_refused_before_any_work(tmp_path_factory, rule) -> None:
    out = tmp_path_factory.mktemp("rec") / "out"
    with pytest.raises(ConfigError, match="calibration"):
        recognition.run(out, objects=["mug"], novel=[], calibration=rule, progress=False)
    assert not out.exists()
    with pytest.raises(ConfigError, match="calibration"):
        recognition.calibrated_thresholds(rule, (0,))


@settings(max_examples=30, deadline=None)
@given(st.one_of(st.just([]), st.just(()), st.lists(st.integers(0, 3), min_size=2, max_size=4).filter(lambda s: len(set(s)) < len(s)),
                 st.lists(st.one_of(st.floats(), st.booleans(), st.text(max_size=2)), min_size=1, max_size=3)))
def test_bad_calibration_seeds_raise_typed_errors(seeds) -> None:
    with pytest.raises(InvalidInputError, match="seed"):
        recognition.calibrated_thresholds(seeds, (0,))


@settings(max_examples=15, deadline=None)
@given(st.one_of(st.floats(max_value=-360.001), st.floats(min_value=360.001), st.just(float("nan")), st.just(float("inf")),
                 st.just(True), st.just("90")))
def test_bad_rolls_are_refused_before_any_work(tmp_path_factory, roll) -> None:
    out = tmp_path_factory.mktemp("rec") / "out"
    with pytest.raises(ConfigError, match="roll_deg"):
        recognition.run(out, objects=["mug"], novel=[], roll_deg=roll, progress=False)
    assert not out.exists()


def test_each_object_gets_its_roll_and_the_thesis_roll_by_default() -> None:
    """roll_job: a torus lying flat is whisked at 0 deg (the array rolled by 90 deg straddles it), the Mug at
    the thesis' 90; with no reach (the Ch.5 study's fixed standoff) every object keeps 90; Setup.roll_of
    gives an unlisted object 90."""
    assert recognition.roll_job(("torus_flat-v0", 3)) == ("torus_flat-v0", 0.0)
    assert recognition.roll_job(("mug", 3)) == ("mug", 90.0)
    assert recognition.roll_job(("torus_flat-v0", 0)) == ("torus_flat-v0", 90.0)
    setup = recognition.Setup(0, 2, 200, (1.0, 0.3), "out", rolls_deg=(("torus_flat-v0", 0.0),))
    assert setup.roll_of("torus_flat-v0") == 0.0 and setup.roll_of("mug") == 90.0


@settings(max_examples=8, deadline=None)
@given(st.one_of(st.floats(max_value=0.0), st.floats(min_value=1.0, exclude_min=True), st.just(float("nan"))))
def test_bad_calibration_quantiles_raise_typed_errors(q) -> None:
    with pytest.raises(InvalidInputError, match="quantile"):
        recognition.calibrated_thresholds("pooled", (0,), quantile=q)


def test_first_seed_calibration_needs_a_seed() -> None:
    with pytest.raises(InvalidInputError, match="first-seed"):
        recognition.calibrated_thresholds("first-seed", ())


@settings(max_examples=30, deadline=None)
@given(k=st.one_of(st.integers(-3, 0), st.floats(allow_nan=True), st.booleans(), st.text(max_size=2), st.none()),
       base=st.one_of(st.integers(-5, 5), st.floats(), st.booleans(), st.none()))
def test_calibration_seeds_refuse_bad_input(k, base) -> None:
    with pytest.raises(InvalidInputError):
        recognition.calibration_seeds(k, 0)
    if not (isinstance(base, int) and not isinstance(base, bool)):
        with pytest.raises(InvalidInputError, match="base"):
            recognition.calibration_seeds(3, base)


def test_calibration_seeds_are_fixed_and_not_study_seeds() -> None:
    """SHA-256 of repr((0, ("calibration", i))), first 4 bytes little-endian (cansim.seeding), by hand."""
    import hashlib

    def by_hand(i: int) -> int:
        return int.from_bytes(hashlib.sha256(repr((0, ("calibration", i))).encode()).digest()[:4], "little")

    seeds = recognition.calibration_seeds()
    assert len(seeds) == recognition.CALIBRATION_SEEDS
    assert seeds == tuple(by_hand(i) for i in range(recognition.CALIBRATION_SEEDS))
    assert len(set(seeds)) == len(seeds) and not set(seeds) & set(range(100))  # no seed a study maps or presents
    assert recognition.calibration_seeds(2) == seeds[:2]  # a prefix: more seeds pool more, never other ones


def _grid(z: float, n: int = 21, half: float = 0.15) -> np.ndarray:
    u = np.linspace(-half, half, n)
    x, y = np.meshgrid(u, u)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)


def test_surface_targets_go_to_the_touched_surface(tmp_path: Path) -> None:
    """Library: a plate at z = 0 and one at z = 0.09 m (9 cm apart, far beyond the residual's
    3-cm cap), loaded from the study's surface files. The arm sits 0.2 m above the origin looking down (-z)
    and feels 5 points of the z = 0 plate per whisk, not moving: every impulse is object 0's."""
    files = []
    for k, z in enumerate((0.0, 0.09)):
        files.append(tmp_path / f"s{k}.npz")
        np.savez_compressed(files[-1], points_m=_grid(z))
    down = Pose.from_rotvec([0.0, 0.0, 0.2], [np.pi, 0.0, 0.0])  # tool z axis along -z of the world
    rng = np.random.default_rng(0)
    contacts = []
    for _ in range(20):
        world = np.c_[rng.uniform(-0.1, 0.1, (5, 2)), np.zeros(5)]
        contacts.append(down.inverse().apply(world))
    still = SpatialOdometry(np.zeros(3), np.zeros(3), 1.0)
    library = recognition.load_surface_library(files, ["low", "high"])
    assert library.names == ("low", "high")
    targets = recognition.surface_targets(library, down, [None] + [still] * 19, contacts)
    assert targets.shape == (20,)
    assert set(targets.tolist()) <= {-1, 0}
    assert np.sum(targets == 0) >= 10  # after the window fills, every whisk


_BAD_SETTINGS = {
    "odometry_scale": st.one_of(st.just(-0.1), st.just(10.5), st.just(float("nan")), st.just(float("inf")), st.just(True),
                                st.just("1")),
    "reach_contacts": st.one_of(st.integers(max_value=-1), st.integers(min_value=19), st.just(1.5), st.just(float("nan")),
                                st.just(True), st.just("3")),
}


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(sorted(_BAD_SETTINGS)).flatmap(lambda k: st.tuples(st.just(k), _BAD_SETTINGS[k])))
def test_bad_study_settings_are_refused_before_any_work(tmp_path_factory, setting) -> None:
    """A bad odometry scale or reach (``run`` and the Ch.5 ``StudyConfig`` its maps use): ConfigError, no file written."""
    from cansim.studies import ch5_object_maps

    name, value = setting
    out = tmp_path_factory.mktemp("rec") / "out"
    with pytest.raises(ConfigError):
        recognition.run(out, objects=["mug"], novel=[], progress=False, **{name: value})
    assert not out.exists()
    with pytest.raises(ConfigError):
        ch5_object_maps.StudyConfig(2, 0.3, {}, None, 0, **{name: value})


def test_odometry_noise_scales_the_thesis_model() -> None:
    """Scale 1 is Eq 6.4-6.11's noise exactly (2.5 deg per Euler angle, 1 cm); 0.25 a quarter of each."""
    import math

    from cansim.studies.ch5_object_maps import odometry_noise
    from whisker_io.sim.odometry_noise import OdometryNoise

    assert odometry_noise(1.0) == OdometryNoise()
    q = odometry_noise(0.25)
    assert q.euler_std_rad == pytest.approx(math.radians(2.5) / 4) and q.displacement_std_m == pytest.approx(0.0025)
    assert q.angular_speed_mean_rad_s == OdometryNoise().angular_speed_mean_rad_s


@settings(max_examples=15, deadline=None)
@given(st.sampled_from(["missing", "not_npz", "no_points", "bad_shape"]))
def test_bad_surface_files_raise_typed_errors(tmp_path_factory, kind) -> None:
    from whisker_io.errors import CorruptFileError, InvalidInputError, ShapeError

    d = tmp_path_factory.mktemp("surf")
    f = d / "s.npz"
    if kind == "not_npz":
        f.write_bytes(b"not a zip")
    elif kind == "no_points":
        np.savez_compressed(f, other=np.zeros(3))
    elif kind == "bad_shape":
        np.savez_compressed(f, points_m=np.zeros((5, 2)))
    with pytest.raises((InvalidInputError, CorruptFileError, ShapeError)):
        recognition.load_surface_library([f], ["x"])


def test_unmapped_contact_fraction_counts_contacts_where_the_map_felt_nothing(tmp_path: Path) -> None:
    """A plate mapped over x, y in [-0.15, 0.15] m at z = 0; the arm 0.2 m above the origin looking down. Of 4 whisks,
    two feel the mapped plate (6 contacts), one feels the plate's continuation 0.3 m away (3 contacts, no stored
    point within reach), one has no contact array: 3 unmapped of 9. Contacts are given in the end-effector frame and
    placed by the true poses (the library's frame)."""
    f = tmp_path / "plate.npz"
    np.savez_compressed(f, points_m=_grid(0.0))
    library = recognition.load_surface_library([f], ["plate"])
    down = Pose.from_rotvec([0.0, 0.0, 0.2], [np.pi, 0.0, 0.0])
    mapped = np.array([[0.0, 0.0, 0.0], [0.02, -0.03, 0.0], [-0.05, 0.04, 0.0]])
    beyond = mapped + [0.3, 0.0, 0.0]
    contacts = [down.inverse().apply(mapped), None, down.inverse().apply(beyond), down.inverse().apply(mapped[::-1])]
    p = np.tile(down.position_m, (4, 1))
    q = np.tile(down.quaternion_xyzw, (4, 1))
    assert recognition.unmapped_contact_fraction(library, 0, p, q, contacts) == pytest.approx(3 / 9)
    assert recognition.unmapped_contact_fraction(library, 0, p[:1], q[:1], contacts[:1]) == 0.0
    assert recognition.unmapped_contact_fraction(library, 0, p[:2], q[:2], [None, np.zeros((0, 3))]) == 0.0
    # the same whisks from poses 0.3 m to the other side: the continuation is now on the plate, the rest is not
    side = np.tile(down.position_m - [0.3, 0.0, 0.0], (4, 1))
    assert recognition.unmapped_contact_fraction(library, 0, side, q, contacts) == pytest.approx(6 / 9)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["library", "index", "index_bool", "p_shape", "p_nan", "q_len", "q_not_unit", "c_len", "c_shape",
                        "c_nan"]))
def test_unmapped_contact_fraction_refuses_bad_input_with_typed_errors(tmp_path_factory, bad) -> None:
    d = tmp_path_factory.mktemp("unm")
    np.savez_compressed(d / "plate.npz", points_m=_grid(0.0))
    library = recognition.load_surface_library([d / "plate.npz"], ["plate"])
    down = Pose.from_rotvec([0.0, 0.0, 0.2], [np.pi, 0.0, 0.0])
    p, q = np.tile(down.position_m, (2, 1)), np.tile(down.quaternion_xyzw, (2, 1))
    c = [np.zeros((3, 3)), None]
    args = dict(library=library, index=0, true_p=p, true_q=q, contacts=c)
    assert recognition.unmapped_contact_fraction(**args) == 1.0  # the good call: 3 contacts at the tool, 0.2 m above the plate
    args.update({
        "library": dict(library="plate"), "index": dict(index=1), "index_bool": dict(index=True),
        "p_shape": dict(true_p=p[:, :2]), "p_nan": dict(true_p=np.where([[True, False, False], [False] * 3], np.nan, p)),
        "q_len": dict(true_q=q[:1]), "q_not_unit": dict(true_q=q * 2.0), "c_len": dict(contacts=c[:1]),
        "c_shape": dict(contacts=[np.zeros((3, 2)), None]), "c_nan": dict(contacts=[np.full((1, 3), np.inf), None]),
    }[bad])
    with pytest.raises((InvalidInputError, ShapeError)):
        recognition.unmapped_contact_fraction(args["library"], args["index"], args["true_p"], args["true_q"], args["contacts"])


@pytest.mark.slow
def test_a_library_object_the_mapping_never_observed_leaves_the_run_finishing(tmp_path: Path) -> None:
    """A flat torus (9 cm high) whisked with the array rolled by the thesis' 90 deg is felt by fewer
    than 3 whiskers at every whisk of A, even reaching for contact, and gets a map without an
    experience; the study's full mode (25 and 50 objects hold such shapes) used to stop on it in
    the thesis library model. Now the run finishes: the flat torus is in the library by name,
    nothing is decided for it by the thesis matcher, the Mug is named. With the roll chosen per
    object (the default) the torus is whisked at 0 deg, observed, and named along A."""
    rows = recognition.run(tmp_path / "out", objects=["mug", "torus_flat-v0"], novel=[], bins=(), seeds=(0,),
                           progress=False, workers=1, roll_deg=90.0)
    assert {(r["matcher"], r["presented"], r["presentation"]) for r in rows} == {
        (m, n, p) for m in recognition.DEFAULT_MATCHERS for n in ("mug", "torus_flat-v0") for p in ("A", "B")}
    thesis = {(r["presented"], r["presentation"]): r for r in rows if r["matcher"] == "thesis"}
    assert thesis["torus_flat-v0", "A"]["impulses_own"] == 0 and thesis["torus_flat-v0", "A"]["whisks_with_contact"] == 0
    assert thesis["mug", "A"]["decision"] == "mug" and thesis["mug", "B"]["decision"] in ("mug", "")
    rows = recognition.run(tmp_path / "rolled", objects=["mug", "torus_flat-v0"], novel=[], bins=(), seeds=(0,),
                           progress=False, workers=1, matchers=("thesis",))
    along_a = {r["presented"]: r for r in rows if r["presentation"] == "A"}
    assert along_a["torus_flat-v0"]["roll_deg"] == 0.0 and along_a["mug"]["roll_deg"] == 90.0
    assert along_a["torus_flat-v0"]["whisks_with_contact"] > 0 and along_a["torus_flat-v0"]["decision"] == "torus_flat-v0"


def test_a_library_object_felt_at_no_point_is_a_typed_error_naming_it(tmp_path: Path, monkeypatch) -> None:
    """The surface matcher needs a felt surface of every library object: one felt at fewer than 3 points stops the
    run after mapping with an error that names the object as given (not its seed name) and what to change."""
    real = recognition.map_job

    def unfelt_box(job):
        out = real(job)
        return dict(out, n_points=0) if job[0] == "box" else out

    monkeypatch.setattr(recognition, "map_job", unfelt_box)
    with pytest.raises(InvalidInputError, match=r"the box was touched at 0 points in its \d+ mapping whisks: the surface "
                                                r"matcher has no surface.*--scale-to-m.*--matchers thesis"):
        recognition.run(tmp_path / "out", objects=["mug", "box"], novel=[], bins=(), seeds=(0,), progress=False,
                        workers=1, matchers=("surface",))
    assert not (tmp_path / "out" / "recognition_runs.csv").exists()  # stopped before any presentation


def test_the_summary_says_what_a_novel_object_was_taken_for_and_counts_presentations() -> None:
    def row(presented, novel, presentation, decision, correct, size=2):
        return {"matcher": "surface", "library_size": size, "seed": 0, "presented": presented, "novel": novel,
                "presentation": presentation, "distance_bin": "", "decision": decision, "correct": correct,
                "whisks": 200, "whisks_with_contact": 180, "unmapped_contact_fraction": ""}

    rows = [row("mug", False, "A", "mug", True), row("barrel", False, "A", "barrel", True),
            row("bucket", True, "A", "barrel", False), row("bucket", True, "B", "barrel", False),
            row("knot", True, "A", "mug", False), row("knot", True, "B", "", True)]
    text = recognition.summary(rows, 60.0, True)
    assert "library of 2 objects" in text and "odometry noise 1 x Eq 6.4-6.11 (the thesis)" in text
    assert "odometry noise 0.25 x Eq 6.4-6.11;" in recognition.summary(rows, 60.0, True, 0.25)
    assert "novel objects  no decision in 1/4 presentations target 95 %: NOT HELD" in text
    alone = recognition.summary([r for r in rows if not r["novel"]], 60.0, True)  # no novel object presented
    assert "novel objects  no decision in 0/0 presentations target 95 %: not measured (no novel object)" in alone
    assert "NOT HELD" not in alone.split("novel objects")[1].splitlines()[0]
    assert "the bucket (novel) was taken for the barrel 2x" in text and "the knot (novel) was taken for the mug 1x" in text
    one = recognition.summary([dict(r, library_size=1) for r in rows[:1]], 60.0, True)
    assert "library of 1 object," in one and "with one library object every decision names it" in one


def test_reaching_for_more_whiskers_than_the_array_has_is_refused() -> None:
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.trajectories import object_trajectory

    with pytest.raises(InvalidInputError, match=r"reach_contacts must be in \[0, 18\] \(the array's 18 whiskers"):
        object_trajectory(make_object("mug"), "A", 1, reach_contacts=19)
    with pytest.raises(SystemExit):
        recognition.main(["--reach-contacts", "19"])
    assert len(object_trajectory(make_object("mug"), "A", 1, reach_contacts=18)) > 3  # all 18: allowed


def test_the_matcher_motion_model_has_a_floor_so_exact_odometry_is_not_a_collapsed_filter(tmp_path: Path,
                                                                                          monkeypatch) -> None:
    """Below maps.pose_graph.MIN_NOISE_SCALE the odometry scale no longer narrows the matcher's motion model (Eq 6.4-6.11's
    2.5 deg per Euler angle and 1 cm per whisk, times the scale); above it the scale is the model's."""
    import maps.surface_match as sm

    files = []
    for k, z in enumerate((0.0, 0.09)):
        files.append(tmp_path / f"s{k}.npz")
        np.savez_compressed(files[-1], points_m=_grid(z))
    down = Pose.from_rotvec([0.0, 0.0, 0.2], [np.pi, 0.0, 0.0])
    contacts = [down.inverse().apply(np.c_[np.linspace(-0.1, 0.1, 5), np.zeros((5, 2))])] * 3
    still = SpatialOdometry(np.zeros(3), np.zeros(3), 1.0)
    library = recognition.load_surface_library(files, ["low", "high"])
    seen = []

    class Spy(sm.SurfaceMatcher):
        def __init__(self, lib, start, config):
            seen.append((config.rotation_sigma_deg, config.displacement_sigma_m))
            super().__init__(lib, start, config)

    monkeypatch.setattr(sm, "SurfaceMatcher", Spy)
    for scale in (0.0, 0.1, 0.25, 0.5, 2.0):
        recognition.surface_targets(library, down, [None, still, still], contacts, scale)
    from maps.pose_graph import MIN_NOISE_SCALE

    assert MIN_NOISE_SCALE == 0.25
    np.testing.assert_allclose(seen, [(2.5 * f, 0.01 * f) for f in (0.25, 0.25, 0.25, 0.5, 2.0)])


@pytest.mark.parametrize("scale,expected", [(0.0, 0.25), (0.5, 0.5), (1.0, 1.0)])
def test_a_map_is_placed_by_a_pose_graph_whose_odometry_edges_are_as_noisy_as_the_odometry(tmp_path: Path, monkeypatch,
                                                                                        scale, expected) -> None:
    """The odometry edges of map_job's pose graph: Eq 6.4-6.11's 1 cm and 2.5 deg times the study's odometry scale
    (at least MIN_NOISE_SCALE), the closures as the default; at scale 1 the default graph itself."""
    import maps.pose_graph as pg

    seen = []
    real = pg.whisk_surface

    def spy(odometry, exp_ids, relocalised, contacts, config=pg.WhiskGraphConfig(), **kw):
        seen.append(config)
        return real(odometry, exp_ids, relocalised, contacts, config, **kw)

    monkeypatch.setattr(pg, "whisk_surface", spy)
    setup = recognition.Setup(seed=0, map_loops=1, whisks=10, thresholds=(1.0, 0.3), out=str(tmp_path),
                              odometry_scale=scale)
    recognition.map_job(("box", setup))
    (config,) = seen
    assert config.odometry_sigma_m == pytest.approx(0.01 * expected)
    assert config.odometry_sigma_deg == pytest.approx(2.5 * expected)
    assert (config.closure_sigma_m, config.closure_sigma_deg) == (0.01, 3.0)


def test_the_confusion_counts_keep_an_object_labelled_none_apart_from_no_decision() -> None:
    """An object may be labelled "none": its column is not the runs that decided nothing (hand-counted)."""
    def run(presented: str, decision: str, novel: bool = False) -> dict:
        return {"presented": presented, "decision": decision, "novel": novel}

    rows = [run("none", "none"), run("none", ""), run("mug", "none"), run("mug", "mug"), run("mug", ""),
            run("knot", "", True), run("knot", "mug", True)]
    presented, decided, counts = recognition.confusion(rows)
    assert presented == ["none", "mug", "knot"]
    assert decided == ["none", "mug", None]  # the novel knot is no column
    assert counts.tolist() == [[1, 0, 1], [1, 1, 1], [0, 1, 1]]
    # one order for every panel of the figure: a panel without the knot keeps its row (of zeros)
    _, _, part = recognition.confusion(rows[:2], presented, decided)
    assert part.tolist() == [[1, 0, 1], [0, 0, 0], [0, 0, 0]]
    assert recognition.NO_DECISION not in {"none", "mug", "knot"}


def test_the_confusion_counts_refuse_a_run_outside_the_rows_and_columns_given() -> None:
    rows = [{"presented": "mug", "decision": "box", "novel": False}]
    with pytest.raises(InvalidInputError, match="decides 'box': not among"):
        recognition.confusion(rows, ["mug"], ["mug", None])
    with pytest.raises(InvalidInputError, match="presents 'mug'"):
        recognition.confusion(rows, ["cup"], ["box", None])


@settings(max_examples=50, deadline=None)
@given(runs=st.lists(st.tuples(st.sampled_from(["mug", "none", "knot"]), st.sampled_from(["mug", "none", ""])),
                     max_size=12))
def test_the_confusion_counts_are_the_runs_counted_by_hand(runs) -> None:
    """Every run lands in exactly one cell: its presented object's row and its decision's column (None: nothing).
    As in the study, every library object a run may decide is presented too (two runs that decide nothing)."""
    runs = [("mug", ""), ("none", ""), *runs]
    rows = [{"presented": p, "decision": d, "novel": p == "knot"} for p, d in runs]
    presented, decided, counts = recognition.confusion(rows)
    assert presented == list(dict.fromkeys(p for p, _ in runs))
    assert decided == [p for p in presented if p != "knot"] + [None]
    for i, p in enumerate(presented):
        for j, d in enumerate(decided):
            by_hand = sum(1 for q, e in runs if q == p and (e or None) == d)
            assert counts[i, j] == by_hand
    assert counts.sum() == len(runs)


def test_an_interrupted_run_keeps_its_finished_seeds_runs_whole(tmp_path: Path, monkeypatch) -> None:
    """Ctrl-C during seed 1's presentations: seed 0's runs are written to recognition_runs_interrupted.csv (whole,
    in the study's columns), no recognition_runs.csv is left; a complete run then writes its CSV and drops the
    interrupted one (the mapping and presentations are stand-ins: this tests the run's bookkeeping)."""
    import csv as _csv

    def fake_map(job):
        name, setup, stem = job
        return {"name": name, "path": str(tmp_path / f"{stem}.npz"), "surface": "", "n_experiences": 3, "n_points": 9,
                "whisks": 10}

    stop_at = {"seed": 1}

    def fake_present(job):
        presented, novel, presentation, vp, lib_paths, names, setup, library = job
        if setup.seed == stop_at["seed"]:
            raise KeyboardInterrupt
        return [{c: "" for c in recognition.COLUMNS} | {"seed": setup.seed, "presented": presented, "novel": novel,
                                                        "presentation": presentation, "decision": presented,
                                                        "library_size": len(names), "matcher": "thesis"}]

    monkeypatch.setattr(recognition, "map_job", fake_map)
    monkeypatch.setattr(recognition, "present_job", fake_present)
    monkeypatch.setattr(recognition, "calibrated_thresholds", lambda *a, **k: (1.0, 0.3))
    out = tmp_path / "out"
    kw = dict(objects=["mug", "box"], novel=[], bins=(), seeds=(0, 1, 2), progress=False, workers=1,
              matchers=("thesis",), roll_deg=90.0, library_sizes=(2,))
    with pytest.raises(KeyboardInterrupt):
        recognition.run(out, **kw)
    assert not (out / "recognition_runs.csv").exists()
    with open(out / recognition.INTERRUPTED_CSV, newline="") as fh:
        kept = list(_csv.DictReader(fh))
    assert tuple(kept[0]) == recognition.COLUMNS
    assert sorted((r["seed"], r["presented"], r["presentation"]) for r in kept) == \
        [("0", "box", "A"), ("0", "box", "B"), ("0", "mug", "A"), ("0", "mug", "B")]
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]
    stop_at["seed"] = -1
    rows = recognition.run(out, **kw)
    assert len(rows) == 12 and (out / "recognition_runs.csv").exists() and not (out / recognition.INTERRUPTED_CSV).exists()


def test_a_bad_calibration_rule_is_refused_before_any_copy_is_written(tmp_path: Path) -> None:
    import trimesh

    from cansim.errors import ConfigError

    trimesh.creation.box(extents=(0.2, 0.2, 0.3)).export(tmp_path / "block.stl")
    with pytest.raises(ConfigError, match="calibration must be one of"):
        recognition.run(tmp_path / "out", objects=[str(tmp_path / "block.stl"), "mug"], novel=[], seeds=(0,),
                        calibration="median", progress=False, workers=1, up_axis="z")
    assert not (tmp_path / "out").exists()


def test_an_interrupt_before_any_seed_finished_keeps_an_earlier_interrupted_runs_rows(tmp_path: Path, monkeypatch) -> None:
    def stop(job):
        raise KeyboardInterrupt

    monkeypatch.setattr(recognition, "map_job", stop)
    monkeypatch.setattr(recognition, "calibrated_thresholds", lambda *a, **k: (1.0, 0.3))
    out = tmp_path / "out"
    out.mkdir()
    (out / recognition.INTERRUPTED_CSV).write_text("seed,presented\n0,mug\n")  # an earlier run's finished seed
    with pytest.raises(KeyboardInterrupt):
        recognition.run(out, objects=["mug", "box"], novel=[], bins=(), seeds=(0,), progress=False, workers=1,
                        matchers=("thesis",), roll_deg=90.0)
    assert (out / recognition.INTERRUPTED_CSV).read_text() == "seed,presented\n0,mug\n"
