"""The Ch.5 study (cansim.studies.ch5_object_maps) and the appended object maps (maps.object_library).

End-to-end outcomes on the study's --quick run (fixed seed): recognition by leaky
integration of re-localisations over appended object maps (Fig 5.16-5.17) and 6-D
localisation against the step size (Fig 5.15).
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.models.whisker_ratslam import WhiskerRatSLAM
from maps.object_library import append_object_maps
from maps.object_map import ObjectMap
from maps.odometry import SpatialOdometry
from whisker_io.errors import CansimError, ConfigError, InvalidInputError

from cansim.studies import ch5_object_maps as ch5_study


def _region(rng: np.random.Generator, k: int) -> tuple[np.ndarray, np.ndarray]:
    pfh = np.zeros(81)
    pfh[k % 81] = 0.6
    pfh[(7 * k + 3) % 81] += 0.4
    return pfh, np.full(18, float(k % 5))


def _toy_model(n_views: int, seed: int) -> WhiskerRatSLAM:
    """A model that whisks distinct regions, then revisits them (re-localisations)."""
    slam = WhiskerRatSLAM(backend="numpy")
    rng = np.random.default_rng(seed)
    for k in list(range(n_views)) * 2:
        slam.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.3], 1.0), _region(rng, k + 11 * seed))
    return slam


@pytest.fixture(scope="module")
def two_maps() -> tuple[WhiskerRatSLAM, WhiskerRatSLAM]:
    return _toy_model(4, 1), _toy_model(3, 2)


def test_append_object_maps_keeps_objects_apart(two_maps: tuple[WhiskerRatSLAM, WhiskerRatSLAM]) -> None:
    a, b = two_maps
    na, nb = a.object_map.n_experiences, b.object_map.n_experiences
    lib = append_object_maps([a.object_map, b.object_map], ["a", "b"], [0, len(a.frontend)])
    m = lib.object_map
    assert m.n_experiences == na + nb
    assert lib.exp_object.tolist() == [0] * na + [1] * nb
    ends = m.to_arrays()["link_ends"]
    assert len(ends) == len(a.object_map.to_arrays()["link_ends"]) + len(b.object_map.to_arrays()["link_ends"])
    assert np.all(lib.exp_object[ends[:, 0]] == lib.exp_object[ends[:, 1]])  # no link between objects
    vt = m.to_arrays()["exp_vt"]
    assert vt[:na].tolist() == a.object_map.to_arrays()["exp_vt"].tolist()
    assert vt[na:].tolist() == (b.object_map.to_arrays()["exp_vt"] + len(a.frontend)).tolist()
    h = m.history
    assert len(h) == len(a.object_map.history) + len(b.object_map.history)
    hb = h[len(a.object_map.history):]
    assert hb.tolist() == [x + na if x >= 0 else -1 for x in b.object_map.history.tolist()]
    assert lib.with_explored(na + nb + 2).tolist()[-2:] == [-1, -1]


def test_library_model_relocalises_to_the_right_object(tmp_path: Path, two_maps: tuple[WhiskerRatSLAM, WhiskerRatSLAM]) -> None:
    a, b = two_maps
    a.save(tmp_path / "a.npz")
    b.save(tmp_path / "b.npz")
    model, lib = ch5_study.library_model([tmp_path / "a.npz", tmp_path / "b.npz"], ["a", "b"])
    assert len(model.frontend) == len(a.frontend) + len(b.frontend)
    rng = np.random.default_rng(0)
    objs = []
    for k in list(range(3)) * 3:  # revisit object b's regions
        s = model.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.3], 1.0), _region(rng, k + 22))
        assert not s.new_view
        if s.relocalised:
            objs.append(int(lib.with_explored(model.object_map.n_experiences)[s.exp_id]))
    assert objs and set(objs) == {1}


@settings(max_examples=40, deadline=None)
@given(
    names=st.lists(st.text(min_size=0, max_size=3), min_size=0, max_size=3),
    offsets=st.lists(st.integers(-3, 5), min_size=0, max_size=3),
    n_maps=st.integers(0, 3),
    empty=st.booleans(),
)
def test_append_object_maps_refuses_bad_input(two_maps: tuple[WhiskerRatSLAM, WhiskerRatSLAM], names: list[str],
                                              offsets: list[int], n_maps: int, empty: bool) -> None:
    a, b = two_maps
    maps = [a.object_map, b.object_map, ObjectMap() if empty else a.object_map][:n_maps]
    ok = (n_maps > 0 and len(names) == len(offsets) == n_maps and len(set(names)) == n_maps
          and all(o >= 0 for o in offsets) and offsets == sorted(offsets)
          and not (empty and n_maps == 3 and ObjectMap().config != a.object_map.config))
    before = [m.n_experiences for m in maps]
    if ok:
        lib = append_object_maps(maps, names, offsets)
        assert lib.object_map.n_experiences == sum(before)
    else:
        with pytest.raises(InvalidInputError):
            append_object_maps(maps, names, offsets)
    assert [m.n_experiences for m in maps] == before  # inputs never change


def test_an_object_map_without_experience_is_appended_under_its_name(two_maps: tuple[WhiskerRatSLAM, WhiskerRatSLAM]) -> None:
    """An object its exploration never observed (no region, no experience) stays in the library by name:
    no experience of it, so nothing re-localises into it; every map empty is refused."""
    a, b = two_maps
    never = WhiskerRatSLAM(backend="numpy")
    never.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.3], 1.0), None)  # odometry only: no region, no experience
    assert never.object_map.n_experiences == 0 and never.object_map.config == a.object_map.config
    with pytest.warns(UserWarning, match="1 object map.* without an experience.*: flat$"):
        lib = append_object_maps([a.object_map, never.object_map, b.object_map], ["a", "flat", "b"],
                                 [0, len(a.frontend), len(a.frontend)])
    na, nb = a.object_map.n_experiences, b.object_map.n_experiences
    assert lib.names == ("a", "flat", "b") and lib.exp_object.tolist() == [0] * na + [2] * nb
    assert len(lib.history_object) == lib.object_map.n_recorded and 1 in lib.history_object.tolist()
    with pytest.raises(InvalidInputError, match="every map is empty"):
        append_object_maps([never.object_map, never.object_map], ["x", "y"], [0, 0])


def test_library_model_warns_of_an_empty_map_unless_its_caller_says_it(tmp_path: Path,
                                                                         two_maps: tuple[WhiskerRatSLAM, WhiskerRatSLAM]) -> None:
    """The studies' jobs build the library for every run and pass ``warn_empty=False`` (their summaries or logs say
    it once); a user's call warns."""
    import warnings

    a, _ = two_maps
    never = WhiskerRatSLAM(backend="numpy")
    never.step(SpatialOdometry([0.1, 0, 0], [0, 0, 0.3], 1.0), None)
    a.save(tmp_path / "a.npz")
    never.save(tmp_path / "never.npz")
    paths = [tmp_path / "a.npz", tmp_path / "never.npz"]
    with pytest.warns(UserWarning, match="without an experience.*: never$"):
        ch5_study.library_model(paths, ["a", "never"])
    with warnings.catch_warnings(record=True) as shown:  # Python's default: once per place in the code
        warnings.simplefilter("default")
        ch5_study.library_model(paths, ["a", "never"])
        ch5_study.library_model(paths, ["a", "never"], warn_empty=False)  # must not reset the record of what was shown
        ch5_study.library_model(paths, ["a", "never"])
    assert len([w for w in shown if "without an experience" in str(w.message)]) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model, lib = ch5_study.library_model(paths, ["a", "never"], warn_empty=False)
    assert lib.names == ("a", "never") and model.object_map.n_experiences == a.object_map.n_experiences


@settings(max_examples=20, deadline=None)
@given(n=st.one_of(st.integers(-5, 100), st.floats(allow_nan=True), st.booleans()))
def test_with_explored_validates(two_maps: tuple[WhiskerRatSLAM, WhiskerRatSLAM], n: object) -> None:
    a, _ = two_maps
    lib = append_object_maps([a.object_map], ["a"], [0])
    n_lib = len(lib.exp_object)
    if isinstance(n, int) and not isinstance(n, bool) and n >= n_lib:
        t = lib.with_explored(n)
        assert len(t) == n and np.all(t[n_lib:] == -1)
    else:
        with pytest.raises(InvalidInputError):
            lib.with_explored(n)  # type: ignore[arg-type]


@settings(max_examples=60, deadline=None)
@given(label=st.one_of(
    st.tuples(st.sampled_from(("pfh", "sda", "both", "PFH", "")), st.sampled_from(("update", "no-update", "off")),
              st.sampled_from(("tip", "svr", "truth"))).map("/".join),
    st.text(max_size=12),
))
def test_id_config_label_parses_or_exits(label: str) -> None:
    parts = label.split("/")
    ok = (len(parts) == 3 and parts[0] in ("pfh", "sda", "both") and parts[1] in ("update", "no-update")
          and parts[2] in ("tip", "svr"))
    if ok:
        c = ch5_study._config(label)
        assert (c.features, c.feature_update, c.contact_model) == (parts[0], parts[1] == "update", parts[2])
        assert c.label == label
    else:
        with pytest.raises(SystemExit, match="--id-config"):
            ch5_study._config(label)


def test_settings_refuse_an_uncalibrated_contact_model() -> None:
    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    assert s.thresholds_for("tip") == (0.9, 0.3)
    with pytest.raises(ConfigError, match="svr"):
        s.thresholds_for("svr")
    cfg = ch5_study._slam_config(ch5_study.Config("both", False, "tip"), s, 0.05)
    assert (cfg.frontend.pfh_threshold, cfg.frontend.sda_threshold) == (0.9, 0.3)
    assert cfg.pose_prior  # the study's default matching: WhiskerRatSLAMConfig.mapping
    thesis = ch5_study._slam_config(ch5_study.Config("both", False, "tip"), dataclasses.replace(s, matching="thesis"), 0.05)
    assert not thesis.pose_prior
    with pytest.raises(ConfigError, match="matching"):
        dataclasses.replace(s, matching="pose")


# ----------------------------------------------------------------- calibration
_GOOD_SEEDS = st.one_of(st.integers(0, 2**40), st.lists(st.integers(-5, 2**40), min_size=1, max_size=4, unique=True))


@settings(max_examples=60, deadline=None)
@given(seed=st.one_of(
    _GOOD_SEEDS,
    st.lists(st.integers(0, 3), min_size=2, max_size=4).filter(lambda s: len(set(s)) < len(s)),  # repeated seeds
    st.just([]), st.just(()), st.booleans(), st.floats(allow_nan=True), st.text(max_size=3), st.none(),
    st.lists(st.one_of(st.floats(), st.booleans(), st.text(max_size=2), st.none()), min_size=1, max_size=3),
    st.lists(st.integers(0, 9), min_size=1, max_size=3).map(lambda s: [*s, 1.5]),
))
def test_calibrate_refuses_bad_seeds(seed: object) -> None:
    ints = isinstance(seed, int) and not isinstance(seed, bool)
    seq = (isinstance(seed, (list, tuple)) and len(seed) > 0
           and all(isinstance(x, int) and not isinstance(x, bool) for x in seed) and len(set(seed)) == len(seed))
    if ints or seq:  # valid: read as the seeds to pool, in order (calibrating them is the slow test's)
        assert ch5_study._calibration_seeds(seed) == ((seed,) if ints else tuple(seed))
    else:
        with pytest.raises(InvalidInputError, match="seed"):
            ch5_study.calibrate(0.3, 0.75, seed)  # type: ignore[arg-type]


@settings(max_examples=20, deadline=None)
@given(noise=st.one_of(st.floats(max_value=-1e-9), st.just(float("nan")), st.just(float("inf")), st.booleans(),
                       st.text(max_size=2), st.none()))
def test_calibrate_refuses_bad_noise_scale(noise: object) -> None:
    with pytest.raises(InvalidInputError, match="noise_scale"):
        ch5_study.calibrate(noise, 0.75, 0)  # type: ignore[arg-type]


@pytest.mark.slow
def test_calibrate_pools_the_seeds_same_pose_distances() -> None:
    one = {s: ch5_study.calibrate(0.3, 0.75, s, "tip") for s in (0, 1)}
    assert ch5_study.calibrate(0.3, 0.75, [0], "tip") == one[0]  # a one-seed pool is that seed's calibration
    ab, ba = (ch5_study.calibrate(0.3, 0.75, s, "tip") for s in ([0, 1], [1, 0]))
    assert ab["n_pairs"] == ba["n_pairs"] == one[0]["n_pairs"] + one[1]["n_pairs"]
    for key in ("pfh_threshold", "sda_threshold"):
        assert ab[key] == pytest.approx(ba[key], rel=1e-12)  # a quantile of the pooled distances: order-free
        # the quantile of a mixture lies between its parts' quantiles
        lo, hi = sorted(one[s][key] for s in (0, 1))
        assert lo - 1e-9 <= ab[key] <= hi + 1e-9, (key, lo, ab[key], hi)


# ----------------------------------------------------------------- the --quick study
@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from entry_point import run_cansim

    out = tmp_path_factory.mktemp("ch5")  # through the installed entry point, as a user runs it
    done = run_cansim("study", "ch5", "--quick", "--out", str(out), "--contacts", "tip", "--workers", "2")
    assert done.returncode == 0, done.stderr[-3000:]
    return out


def _rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path) as f:
        r = csv.DictReader(f)
        return list(r.fieldnames or []), list(r)


@pytest.mark.slow
def test_quick_writes_the_outputs(quick: Path) -> None:
    cols, loc = _rows(quick / "ch5_localisation.csv")
    assert {"object", "features", "feature_update", "contact_model", "position_error_m", "rotation_error_deg",
            "step_translation_m", "step_rotation_deg"} <= set(cols)
    assert loc and {r["object"] for r in loc} == {"mug", "box", "plane"}
    cols, ids = _rows(quick / "ch5_identification.csv")
    assert {"presented", "trajectory", "map_identity", "max_confidence", "final_ic", "threshold", "rc_decision",
            "ic_decision"} <= set(cols)
    assert {r["trajectory"] for r in ids} == {"A", "B"}
    assert "skull" in {r["presented"] for r in ids} and "skull" not in {r["map_identity"] for r in ids}
    assert {r["matching"] for r in loc} == {"mapping", "thesis"}  # the study's matching and the comparison
    cols, cal = _rows(quick / "ch5_calibration.csv")
    assert {"contact_model", "noise_scale", "quantile", "n_pairs", "pfh_threshold", "sda_threshold"} <= set(cols)
    assert [r["contact_model"] for r in cal] == ["tip"]
    for name in ("fig5_14b_dead_reckoning.png", "fig5_15_localisation.png", "fig5_16_history.png", "fig5_17_confidence.png",
                 "ch5_summary.txt"):
        assert (quick / name).stat().st_size > 0


def _id(quick: Path) -> list[dict[str, str]]:
    return _rows(quick / "ch5_identification.csv")[1]


@pytest.mark.slow
def test_own_map_has_the_highest_ic_under_a(quick: Path) -> None:
    rows = [r for r in _id(quick) if r["trajectory"] == "A" and r["presented"] != "skull"]
    for p in {r["presented"] for r in rows}:
        mine = [r for r in rows if r["presented"] == p]
        win = max(mine, key=lambda r: float(r["final_ic"]))
        assert win["map_identity"] == p, (p, [(r["map_identity"], r["final_ic"]) for r in mine])


@pytest.mark.slow
def test_novel_object_stays_below_the_threshold(quick: Path) -> None:
    rows = [r for r in _id(quick) if r["presented"] == "skull"]
    assert rows
    for r in rows:
        assert float(r["max_confidence"]) < float(r["threshold"]), r


@pytest.mark.slow
def test_trajectory_b_gives_lower_confidence_than_a(quick: Path) -> None:
    rows = [r for r in _id(quick) if r["presented"] == r["map_identity"]]
    mean = {f: np.mean([float(r["mean_confidence"]) for r in rows if r["trajectory"] == f]) for f in "AB"}
    assert mean["B"] < mean["A"], mean


@pytest.fixture(scope="module")
def svr_settings(tmp_path_factory: pytest.TempPathFactory) -> ch5_study.StudyConfig:
    """The study's reduced localisation settings: 2 loops, SVR thresholds calibrated as the study does."""
    model = ch5_study._ensure_radial_model(None, tmp_path_factory.mktemp("ch5_radial"))
    cal = ch5_study.calibrate(ch5_study.DEFAULT_NOISE_SCALE, 0.75, 0, "svr", model)
    assert cal["contact_model"] == "svr" and cal["n_pairs"] > 0
    return ch5_study.StudyConfig(2, ch5_study.DEFAULT_NOISE_SCALE, {"svr": (cal["pfh_threshold"], cal["sda_threshold"])},
                              model, 0)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mug", "box"])
def test_both_features_svr_localise_below_the_step(svr_settings: ch5_study.StudyConfig, name: str) -> None:
    for seed in (0, 1, 2):
        b = ch5_study.build_job((name, ch5_study.BEST, dataclasses.replace(svr_settings, seed=seed), None))
        assert b["matching"] == "mapping"
        assert len(b["position_m"]) > 0, (name, seed)
        assert np.median(b["position_m"]) < b["step_m"], (name, seed, np.median(b["position_m"]), b["step_m"])
        assert np.median(b["rotation_deg"]) < b["step_deg"], (name, seed, np.median(b["rotation_deg"]), b["step_deg"])


# ----------------------------------------------------------------- a user's mesh files
@pytest.mark.slow
def test_a_users_mesh_files_run_through_the_study_with_their_maps_in_out(tmp_path: Path, monkeypatch) -> None:
    """A millimetre, y-up mesh given by a relative path with --scale-to-m / --up-axis; an unreachable flat disk.

    The maps go to ``ch5_maps/<stem>.npz`` under ``--out`` (never beside the user's file), the summary names
    the novel objects given (two) and prints no NaN."""
    import trimesh

    from whisker_io.sim.objects import load_object, make_object

    folder = tmp_path / "my meshes"
    folder.mkdir()
    mug = make_object("mug").copy()
    mug.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))  # z up -> y up
    mug.apply_scale(1000.0)  # metres -> millimetres
    mug.export(folder / "My Mug.stl")
    disk = trimesh.creation.cylinder(radius=0.175, height=0.02, sections=48)  # flat: no whisk touches it with 3 whiskers
    disk.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    disk.apply_scale(1000.0)
    disk.export(folder / "disk.obj")
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert ch5_study.main(["--quick", "--out", str(out), "--objects", "my meshes/My Mug.stl", "my meshes/disk.obj", "box",
                           "--novel", "plane", "skull", "--scale-to-m", "0.35", "--up-axis", "y", "--contacts", "tip",
                           "--no-compare", "--workers", "1"]) == 0
    assert sorted(p.name for p in folder.iterdir()) == ["My Mug.stl", "disk.obj"]  # nothing written beside them
    assert sorted(p.name for p in (out / "ch5_maps").iterdir()) == ["My_Mug.npz", "box.npz", "disk.npz"]
    # the copies in the conventions: the mug upright and 0.35 m tall as the registered one, on z = 0
    conformed = load_object(out / "objects" / "My_Mug.ply").mesh
    assert conformed.extents == pytest.approx(make_object("mug").extents * 0.35 / make_object("mug").extents.max(), abs=1e-6)
    assert conformed.bounds[0, 2] == pytest.approx(0.0, abs=1e-12)
    assert not (out / "objects" / "box.ply").exists()  # a named object is not copied
    fields, ids = _rows(out / "ch5_identification.csv")
    assert fields[-2:] == ["n_observations", "mesh_file"]
    # one name per object, the map file's stem; the file it was loaded from beside it
    assert {(r["presented"], r["mesh_file"]) for r in ids} == {
        ("My_Mug", str(out / "objects" / "My_Mug.ply")), ("disk", str(out / "objects" / "disk.ply")), ("box", ""), ("plane", ""), ("skull", "")}
    assert {r["map_identity"] for r in ids} == {"My_Mug", "disk", "box"}
    assert {r["n_observations"] for r in ids if r["presented"] == "disk"} == {"0"}  # never a region
    assert all(int(r["n_observations"]) > int(r["n_iterations"]) // 2 for r in ids if r["presented"] == "My_Mug")
    mug_rows = [r for r in ids if r["presented"] == "My_Mug" and r["trajectory"] == "A"]
    assert mug_rows and max(mug_rows, key=lambda r: float(r["final_ic"]))["map_identity"] == mug_rows[0]["presented"]
    text = (out / "ch5_summary.txt").read_text()
    assert "nan" not in text.lower().replace("nanmedian", "")
    assert "undefined" in text  # the disk: no re-localisation
    assert "Reaching: the thesis' fixed standoff touches the disk (roll" in text  # the one object whisked reaching
    # --contacts tip: the thesis' best configuration (SVR contacts) never ran, so finding 3 is not measured
    third = next(line for line in text.splitlines() if "the lowest errors come from" in line)
    assert "NOT measured" in third and "REPRODUCED" not in third
    assert "here plane, skull" in text  # every novel object given, in the summary's finding 4


# ----------------------------------------------------------------- shapes the thesis' poses miss
@pytest.mark.slow
def test_a_flat_mesh_the_thesis_poses_miss_is_mapped_and_identified_reaching(tmp_path: Path) -> None:
    """A torus lying flat (a user's mesh file) is touched by 3 whiskers at no pose of the thesis' fixed standoff:
    mapping and identification then reach for 3 whiskers at the roll that touches it, and the map holds
    experiences; the Mug keeps the thesis' poses (its map the one made along the fixed standoff)."""
    from whisker_io.sim.catalogue import resolve_object
    from whisker_io.sim.trajectories import object_trajectory, touch_share

    torus = resolve_object("torus_flat").mesh
    path = tmp_path / "ring.obj"
    torus.export(path)
    assert touch_share(torus, object_trajectory(torus, "A", 1, step_m=ch5_study.STEP[0], step_deg=ch5_study.STEP[1])) == 0.0
    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    cfg = ch5_study.Config("both", False, "tip")
    slam, poses, log = ch5_study.map_object(str(path), cfg, s)
    assert slam.object_map.n_experiences > 0.3 * len(poses)
    fixed = object_trajectory(torus, "A", 1, step_m=ch5_study.STEP[0], step_deg=ch5_study.STEP[1])
    assert any(not np.allclose(p.position_m, q.position_m) for p, q in zip(poses, fixed))  # the poses reached
    slam.save(tmp_path / "ring.npz")
    res = ch5_study.identify_job((str(path), "B", [str(tmp_path / "ring.npz")], ["ring"], cfg, s))
    assert (np.asarray(res["targets"]) == 0).sum() > 0  # along B it re-localises to its own map (none at the standoff)
    mug_slam, mug_poses, _ = ch5_study.map_object("mug", cfg, s)
    mug_fixed = object_trajectory(resolve_object("mug").mesh, "A", 1, step_m=ch5_study.STEP[0], step_deg=ch5_study.STEP[1])
    assert all(np.array_equal(p.position_m, q.position_m) for p, q in zip(mug_poses, mug_fixed))


@pytest.mark.parametrize("name", [*ch5_study.MAPPED, ch5_study.NOVEL])
def test_every_thesis_object_keeps_the_fixed_standoff(name: str) -> None:
    """The thesis' objects are touched by 3 whiskers at half the poses of trajectory A or more (the blob at
    0.57, the closest), so the Ch.5 study whisks them at the thesis' fixed standoff and roll."""
    from whisker_io.sim.catalogue import resolve_object

    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    assert ch5_study.trajectory_choice(resolve_object(name).mesh, s, *ch5_study.step_of(name)) == (0, 90.0)


def test_trajectory_choice_follows_the_study_config() -> None:
    """A flat torus reaches (roll 0) only with reach_contacts 0 and reach_when_missed; a count given is kept,
    and reach_when_missed=False (the recognition study's --reach-contacts 0) keeps the fixed standoff and roll."""
    from whisker_io.sim.catalogue import resolve_object

    torus = resolve_object("torus_flat").mesh
    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    assert ch5_study.trajectory_choice(torus, s, *ch5_study.STEP) == (3, 0.0)
    assert ch5_study.trajectory_choice(torus, dataclasses.replace(s, reach_when_missed=False), *ch5_study.STEP, 45.0) == (0, 45.0)
    assert ch5_study.trajectory_choice(torus, dataclasses.replace(s, reach_contacts=5), *ch5_study.STEP, 45.0) == (5, 45.0)
    with pytest.raises(ConfigError):
        dataclasses.replace(s, reach_when_missed="yes")


def _id_row(presented: str, fam: str, max_confidence: float, observations: int, fired: bool = False) -> dict:
    return dict(presented=presented, trajectory=fam, map_identity="mug", max_confidence=max_confidence,
                mean_confidence=max_confidence / 2, final_ic=100 * max_confidence, threshold=ch5_study.RC_THRESHOLD,
                ic_threshold=ch5_study.IC_THRESHOLD, rc_decision=False, ic_decision=fired, ic_crossing_iteration=-1,
                n_relocalisations=0, n_iterations=100, n_loops=1, n_observations=observations)


def _finding(text: str, number: str) -> str:
    return next(line for line in text.splitlines() if line.strip().startswith(number))


def test_the_summary_judges_only_what_was_measured() -> None:
    """Made-up runs: a novel object's low confidence counts only from runs that touched it (a region in half the
    whisks or more); high confidence fails whatever the touch; a finding about the thesis' best configuration
    is not measured when it did not run, nor a comparison of configurations when only one ran."""
    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    build = dict(object="mug", config=ch5_study.BEST, position_m=[0.0], rotation_deg=[0.0], step_m=0.1, step_deg=10.0,
                 n_experiences=1, n_regions=1, n_iterations=10, dr_error_m=[0.0], matching="mapping")
    own = _id_row("mug", "A", 5.0, 90)

    def text(ids: list, star: ch5_study.Config = ch5_study.BEST, builds: list | None = None) -> str:
        return ch5_study.summary(builds or [build], ids, [], s, star, True)

    seldom_only = text([own, _id_row("skull", "A", 0.1, 10)])
    assert "NOT measured: every novel run" in _finding(seldom_only, "4.") and "says little" in _finding(seldom_only, "7.")
    mixed = text([own, _id_row("skull", "A", 0.1, 10), _id_row("duck", "A", 0.2, 90)])
    assert "REPRODUCED (seldom touched, not judged: skull (A))" in _finding(mixed, "4.")
    assert "correct: novel; seldom touched: skull (A)" in _finding(mixed, "7.")
    high = text([own, _id_row("skull", "A", 7.0, 10, fired=True)])  # above the RC threshold, seldom touched or not
    assert _finding(high, "4.").endswith("NOT reproduced.") and "fired for mug (A)" in _finding(high, "7.")
    assert "NOT measured: one configuration ran" in _finding(high, "3.")
    tip = ch5_study.Config("both", False, "tip")
    other = text([own], star=tip, builds=[dict(build, config=tip), dict(build, config=ch5_study.Config("pfh", False, "tip"))])
    assert f"NOT measured: {ch5_study.BEST.label} did not run" in _finding(other, "1.")
    assert f"NOT measured: {ch5_study.BEST.label} did not run" in _finding(other, "3.")


def test_a_map_without_an_experience_is_warned_of_once_and_left_out_of_the_findings() -> None:
    """A library mesh no mapping whisk touched with 3 whiskers: one warning in the summary, and findings 1 and 6
    judge the other maps (NOT measured when none is left) instead of failing for it."""
    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    mug = dict(object="mug", config=ch5_study.BEST, position_m=[0.0], rotation_deg=[0.0], step_m=0.1, step_deg=10.0,
               n_experiences=5, n_regions=5, n_iterations=64, dr_error_m=[0.0], matching="mapping")
    cube = dict(mug, object="cube_3cm", position_m=[], rotation_deg=[], n_experiences=0, n_regions=0)
    own = _id_row("mug", "A", 5.0, 90)
    cube_run = dict(_id_row("cube_3cm", "A", 0.0, 0), map_identity="cube_3cm")
    ids = [own, dict(own, trajectory="B"), cube_run, dict(cube_run, trajectory="B")]
    text = ch5_study.summary([mug, cube], ids, [], s, ch5_study.BEST, True)
    warned = [line for line in text.splitlines() if line.startswith("Warning:")]
    assert len(warned) == 1 and "the map of the cube_3cm holds no experience: none of its 64 mapping whisks" in warned[0]
    assert _finding(text, "1.").endswith("REPRODUCED (not judged: cube_3cm, a map without an experience).")
    assert "REPRODUCED (not judged: cube_3cm, a map without an experience)." in _finding(text, "6A.")
    only_cube = ch5_study.summary([cube], [cube_run], [], s, ch5_study.BEST, True)
    assert "NOT measured: no non-Kettle map holds an experience" in _finding(only_cube, "1.")
    assert "NOT measured: no presented object has a map with an experience" in _finding(only_cube, "6A.")
    assert ch5_study.empty_maps([mug], {"mug": "mug"}) == []
    # the identification maps are the best configuration's: an empty map of another configuration leaves the
    # object in the findings, and no warning
    tip = ch5_study.Config("both", False, "tip")
    other_empty = ch5_study.summary([mug, dict(mug, config=tip, position_m=[], rotation_deg=[], n_experiences=0)],
                                    [own, dict(own, trajectory="B")], [], s, ch5_study.BEST, True)
    assert "Warning:" not in other_empty and "not judged" not in _finding(other_empty, "6A.")
    nothing_mapped_shown = ch5_study.summary([mug], [_id_row("duck", "A", 0.1, 90)], [], s, ch5_study.BEST, True)
    assert "NOT measured: no mapped object was presented" in _finding(nothing_mapped_shown, "6A.")
    kettle_only = ch5_study.summary([dict(mug, object="kettle")], [], [], s, ch5_study.BEST, True)
    assert "NOT measured: no object but the Kettle ran" in _finding(kettle_only, "1.")


@settings(max_examples=25, deadline=None)
@given(reach=st.integers(0, 18), missed=st.booleans(), roll=st.floats(-180.0, 180.0),
       step=st.one_of(st.just(ch5_study.STEP), st.tuples(st.floats(-1.0, 0.0), st.floats(-10.0, 10.0))))
def test_trajectory_choice_keeps_a_given_count_and_roll_or_raises_a_typed_error(reach: int, missed: bool, roll: float,
                                                                                step: tuple[float, float]) -> None:
    """Any settings: a count given (or reaching turned off) comes back with the roll as given, untouched; otherwise
    the Box (touched at most poses of the thesis' loop) keeps the standoff and the roll; a bad step is the
    project's typed error."""
    from whisker_io.sim.objects import make_object

    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0, reach_contacts=reach, reach_when_missed=missed)
    try:
        got = ch5_study.trajectory_choice(make_object("box"), s, *step, roll)
    except (InvalidInputError, ConfigError):
        assert step != ch5_study.STEP and reach == 0 and missed  # only a bad step, and only when a loop is built
        return
    assert got == (reach, roll)


def test_training_the_ch4_model_for_the_svr_contacts_is_announced(tmp_path: Path, monkeypatch, caplog) -> None:
    """The study trains the Ch.4 model once when no --radial-model is given, and says so before it starts."""
    import logging

    from cansim.studies import ch4_radial_distance

    calls = []
    monkeypatch.setattr(ch4_radial_distance, "main", lambda argv: calls.append(argv) or 0)
    with caplog.at_level(logging.INFO, logger="ch5_study"):
        path = ch5_study._ensure_radial_model(None, tmp_path)
    assert calls == [["--quick", "--out", str(tmp_path / "ch5_radial")]] and path == str(tmp_path / "ch5_radial" / "svr9.skops")
    assert any("training it once" in r.getMessage() and "--radial-model PATH reuses one" in r.getMessage()
               for r in caplog.records)
    assert ch5_study._ensure_radial_model("given.skops", tmp_path) == "given.skops" and len(calls) == 1
    ch5_study._ensure_radial_model(None, tmp_path / "quiet", progress=False)  # --no-progress reaches the Ch.4 run
    assert calls[-1] == ["--quick", "--out", str(tmp_path / "quiet" / "ch5_radial"), "--no-progress"]


def test_the_svr_models_extrapolation_is_said_once_naming_the_whiskers_outside_its_lengths() -> None:
    """The study's 18-whisker array has 60, 100 and 160-mm whiskers (Sec 6.1.3.1.2); a model trained on 65-137 mm
    (the margin of TrainedModel.predict's warning: 10 % of 137 mm) extrapolates on the 160-mm ones only."""
    note = ch5_study._extrapolation_note("svr9.skops", {"WL": (0.065, 0.137), "CA": (586.1, 2004.0), "AV": (1.0, 5.0)})
    assert "svr9.skops" in note and "WL 0.065 to 0.137 m" in note and "CA 586.1 to 2004 counts" in note
    assert "the array's 160-mm whiskers" in note and "60-mm" not in note.replace("160-mm", "") and "100-mm" not in note
    wide = ch5_study._extrapolation_note("m.skops", {"WL": (0.05, 0.2)})
    assert "whiskers (Sec" not in wide and "extrapolations" in wide
    assert "whiskers (Sec" not in ch5_study._extrapolation_note("svr10.skops", {"CA": (586.1, 2004.0)})  # no WL input


def test_maps_an_earlier_run_left_in_the_folder_are_named(tmp_path: Path) -> None:
    for name in ("mug.npz", "barrel.npz", "kettle.npz", "notes.txt"):
        (tmp_path / name).write_bytes(b"")
    assert ch5_study._stale_maps(tmp_path, [str(tmp_path / "mug.npz"), tmp_path / "box.npz"]) == ["barrel.npz", "kettle.npz"]
    assert ch5_study._stale_maps(tmp_path, [tmp_path / n for n in ("mug.npz", "barrel.npz", "kettle.npz")]) == []


def test_a_bad_object_leaves_no_out_folder_behind(tmp_path: Path) -> None:
    """Every argument is checked before --out is made: a refused run left an empty folder (a student's pass)."""
    out = tmp_path / "never"
    with pytest.raises((SystemExit, CansimError)):
        ch5_study.main(["--quick", "--out", str(out), "--objects", "mug", "--novel", "mug"])
    assert not out.exists()


def test_the_objects_help_lists_every_registered_name(capsys) -> None:
    """Its error message lists every registered object; the help did not (Box-Stack and Skull were missing)."""
    from whisker_io.sim.objects import OBJECT_NAMES

    with pytest.raises(SystemExit):
        ch5_study.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"registered names ({', '.join(OBJECT_NAMES)})" in text and {"box_stack", "skull"} <= set(OBJECT_NAMES)


def test_without_a_novel_object_findings_4_and_7_are_not_measured():
    """cansim study ch5 --novel (nothing after the flag) said "NOT reproduced" and "every novel run seldom touched" of
    runs that never happened (review, session 48)."""
    s = ch5_study.StudyConfig(1, 0.3, {"tip": (0.9, 0.3)}, None, 0)
    build = dict(object="mug", config=ch5_study.BEST, position_m=[0.0], rotation_deg=[0.0], step_m=0.1, step_deg=10.0,
                 n_experiences=1, n_regions=1, n_iterations=10, dr_error_m=[0.0], matching="mapping")
    text = ch5_study.summary([build], [_id_row("mug", "A", 5.0, 90), _id_row("mug", "B", 5.0, 90)], [], s,
                             ch5_study.BEST, True, notes=["A note said once"])
    assert text.count("A note said once.") == 1
    for finding in ("4.", "7."):
        line = _finding(text, finding)
        assert "NOT measured: no novel object was presented" in line and "NOT reproduced" not in line, line
