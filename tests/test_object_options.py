"""The runners' object options (cansim.studies.object_options), the summaries' numbers (cansim.studies.report),
the surface grid's size (maps.surface_field.grid_cells) and the Ch.6 study's seldom-touched warning."""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import CansimError, InvalidInputError
from cansim.studies.object_options import SOURCES_FILE, add_mesh_options, conform_objects, is_mesh_file, object_label
from cansim.studies.report import fmt
from maps.surface_field import MAX_CELLS, SurfaceFieldConfig, grid_cells
from whisker_io.sim.objects import load_object


def _brick_mm_y_up(path: Path) -> None:
    """A 100 x 350 x 200 mm brick, y up (its height, 350 mm, along y)."""
    trimesh.creation.box(extents=(100.0, 350.0, 200.0)).export(path)


def test_mesh_files_are_copied_in_the_conventions_and_names_pass(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    _brick_mm_y_up(a / "brick.stl")
    _brick_mm_y_up(b / "brick.obj")
    out = tmp_path / "out" / "objects"
    got = conform_objects([str(a / "brick.stl"), "mug", str(b / "brick.obj")], out, scale_to_m=0.35, up_axis="y")
    assert got[1] == "mug"
    assert got[0] == str(out / "a_brick.ply") and got[2] == str(out / "b_brick.ply")  # one stem twice: with their folders
    for path in (got[0], got[2]):
        mesh = load_object(path).mesh  # the copy is in the conventions already: loading changes nothing but placement
        assert mesh.extents == pytest.approx([0.1, 0.2, 0.35], abs=1e-6)  # by hand: y (350 mm) up; PLY holds float32
        assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-12)
    assert sorted(p.name for p in a.iterdir()) == ["brick.stl"]  # the user's folder untouched
    # sources.json: which file each copy came from, and what was changed (the named object has no entry)
    sources = json.loads((out / SOURCES_FILE).read_text())
    assert [(e["given"], e["copy"]) for e in sources] == [(str(a / "brick.stl"), got[0]), (str(b / "brick.obj"), got[2])]
    for e in sources:
        assert e["given_path"] == str(Path(e["given"]).resolve())
        assert e["scale_factor"] == pytest.approx(0.35 / 350.0)  # by hand: 350 mm -> 0.35 m
        assert e["extents_m"] == pytest.approx([0.1, 0.2, 0.35])
        assert any(c.startswith("rotated") for c in e["changes"]) and any(c.startswith("scaled") for c in e["changes"])
    assert not list(out.glob(".*.tmp"))  # written whole, no temporary left
    # a later run into the same folder: a bad name fails before anything is written, and a run that copies nothing
    # leaves no earlier run's record behind
    with pytest.raises(InvalidInputError, match="teapot"):
        conform_objects([str(a / "brick.stl"), "teapot"], out, scale_to_m=0.7, up_axis="y")
    assert load_object(got[0]).mesh.extents.max() == pytest.approx(0.35, abs=1e-6)  # the copy not rewritten at 0.7 m
    assert json.loads((out / SOURCES_FILE).read_text()) == sources  # nor its record
    assert conform_objects(["mug", "box"], out) == ["mug", "box"] and not (out / SOURCES_FILE).exists()


def test_mesh_files_come_back_as_absolute_paths_given_relative(tmp_path, monkeypatch):
    """The studies write the returned specs into their CSVs: a mesh file named relative to the working directory
    comes back absolute, copied or not, so the CSVs name one file wherever they are read from."""
    _brick_mm_y_up(tmp_path / "brick.stl")
    trimesh.creation.box(extents=(0.2, 0.3, 0.35)).export(tmp_path / "box_m.stl")
    (tmp_path / "mug_scan.stl").symlink_to(tmp_path / "box_m.stl")  # a link keeps its own name: the object's
    monkeypatch.chdir(tmp_path)
    here = Path.cwd()
    kept = conform_objects(["box_m.stl", "mug", "mug_scan.stl"], "objects")
    assert kept == [str(here / "box_m.stl"), "mug", str(here / "mug_scan.stl")]
    (copy,) = conform_objects(["brick.stl"], "objects", scale_to_m=0.35, up_axis="y")
    assert copy == str(here / "objects" / "brick.ply")
    assert json.loads((tmp_path / "objects" / SOURCES_FILE).read_text())[0]["copy"] == copy


def test_the_folder_may_be_given_as_text_and_anything_else_is_refused(tmp_path):
    _brick_mm_y_up(tmp_path / "brick.stl")
    (copy,) = conform_objects([str(tmp_path / "brick.stl")], str(tmp_path / "objects"), scale_to_m=0.35, up_axis="y")
    assert Path(copy).parent == tmp_path / "objects" and Path(copy).is_file()
    with pytest.raises(InvalidInputError, match="folder must be a path"):
        conform_objects(["mug"], 3)  # type: ignore[arg-type]


def test_the_copy_of_an_earlier_run_is_not_changed_again_in_place(tmp_path):
    _brick_mm_y_up(tmp_path / "brick.stl")
    (copy,) = conform_objects([str(tmp_path / "brick.stl")], tmp_path / "objects", scale_to_m=0.35, up_axis="y")
    before = Path(copy).read_bytes()
    with pytest.raises(InvalidInputError, match="where this run writes a copy"):
        conform_objects([copy], tmp_path / "objects", up_axis="y")  # would turn it a second time, over itself
    assert Path(copy).read_bytes() == before


def test_a_copy_is_never_written_over_a_file_still_to_be_read(tmp_path):
    """y/a/cup.stl's copy went to objects/cup_2.ply before that file, given third, was read."""
    for folder in ("x/a", "y/a", "objects"):
        (tmp_path / folder).mkdir(parents=True)
    trimesh.creation.cylinder(radius=0.1, height=0.3).export(tmp_path / "x" / "a" / "cup.stl")
    trimesh.creation.icosphere(radius=0.15).export(tmp_path / "y" / "a" / "cup.stl")
    # where the second's copy goes: the two cups clash by stem, folder and ending, so all three are numbered
    third = tmp_path / "objects" / "cup_2.ply"
    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(third)
    before = third.read_bytes()
    with pytest.raises(InvalidInputError, match="where this run writes a copy"):
        conform_objects([str(tmp_path / "x" / "a" / "cup.stl"), str(tmp_path / "y" / "a" / "cup.stl"), str(third)],
                        tmp_path / "objects", scale_to_m=0.35)
    assert third.read_bytes() == before and not (tmp_path / "objects" / "cup_1.ply").exists()


def test_seed_names_follow_the_file_not_its_path(tmp_path, monkeypatch):
    from cansim.studies.object_options import check_distinct, seed_name

    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    trimesh.creation.cylinder(radius=0.1, height=0.3).export(tmp_path / "a" / "cup.stl")
    trimesh.creation.icosphere(radius=0.15).export(tmp_path / "b" / "cup.stl")
    monkeypatch.chdir(tmp_path)
    assert seed_name("a/cup.stl") == seed_name(str(tmp_path / "a" / "cup.stl"))  # one file, two spellings
    assert seed_name("a/cup.stl") != seed_name("b/cup.stl")  # two files of one stem: independent noise
    assert seed_name("a/cup.stl").startswith("cup-") and seed_name("mug") == "mug"
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "tin.stl").write_bytes((tmp_path / "a" / "cup.stl").read_bytes())
    with pytest.raises(InvalidInputError, match="given twice"):
        check_distinct(["a/cup.stl", "c/tin.stl"])  # the same mesh under two names


def test_without_the_options_nothing_is_copied(tmp_path, caplog):
    path = tmp_path / "cube.obj"
    trimesh.creation.box(extents=(0.2, 0.2, 0.3)).export(path)
    with caplog.at_level("WARNING", logger="cansim.studies.object_options"):
        assert conform_objects([str(path), "box"], tmp_path / "objects") == [str(path), "box"]
    # what was assumed is said once, with the size as run, for the file (not for the named box)
    (said,) = [r.getMessage() for r in caplog.records]
    assert said.startswith(f"{path}: 0.200 x 0.200 x 0.300 m; assumed in metres and z up")
    assert sorted(p.name for p in (tmp_path / "objects").iterdir()) == ["sources.json"]  # no copy, only the record
    (entry,) = json.loads((tmp_path / "objects" / "sources.json").read_text())
    assert entry["copy"] is None and entry["given"] == str(path)
    assert any(n.startswith("assumed in metres and z up") for n in entry["changes"])


def test_options_without_a_mesh_file_are_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="apply to mesh files"):
        conform_objects(["mug", "box"], tmp_path, scale_to_m=0.35)
    with pytest.raises(InvalidInputError, match="apply to mesh files"):
        conform_objects([], tmp_path, up_axis="y")


def test_a_millimetre_file_without_the_option_names_the_flag(tmp_path):
    _brick_mm_y_up(tmp_path / "brick.stl")
    with pytest.raises(InvalidInputError, match="--scale-to-m 0.35"):
        conform_objects([str(tmp_path / "brick.stl")], tmp_path / "objects")


@settings(max_examples=40, deadline=None)
@given(spec=st.one_of(st.text(max_size=12), st.sampled_from(["teapot", "x.obj", "dir/none.stl", ""])),
       scale=st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True), st.just(0.35)),
       up=st.one_of(st.none(), st.text(max_size=3), st.sampled_from(["y", "-z"])))
def test_conform_objects_fuzz(tmp_path_factory, spec, scale, up):
    """Any input: a list of objects back, or the project's typed error - never another exception."""
    folder = tmp_path_factory.mktemp("objects")
    try:
        got = conform_objects([spec], folder, scale_to_m=scale, up_axis=up)
    except CansimError:
        return
    assert len(got) == 1
    sources = folder / SOURCES_FILE
    if got[0] != spec:  # a copy was made: its source is recorded
        assert [e["copy"] for e in json.loads(sources.read_text())] == got
    else:
        assert not sources.exists()


def test_labels_and_mesh_files():
    assert is_mesh_file("/data/My Mug.OBJ") and is_mesh_file("x.glb") and not is_mesh_file("mug")
    assert object_label("/data/My Mug.OBJ") == "My_Mug" and object_label("torus_flat-v3") == "torus_flat-v3"


def test_the_options_parse():
    ap = argparse.ArgumentParser()
    add_mesh_options(ap)
    a = ap.parse_args(["--scale-to-m", "0.3", "--up-axis", "y"])
    assert (a.scale_to_m, a.up_axis) == (0.3, "y")
    assert (ap.parse_args([]).scale_to_m, ap.parse_args([]).up_axis) == (None, None)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_fmt_never_prints_nan(value):
    text = fmt(value)
    assert "nan" not in text and "inf" not in text
    assert (text == "undefined") == (not math.isfinite(value))
    if math.isfinite(value):
        assert text == f"{value:.3f}"


def test_grid_cells_by_hand():
    # a 0.3 m cube of points at 7.5 mm with 5 cm of reach: (0.3 + 0.1) / 0.0075 = 53.3 -> 54 + 1 = 55 cells an axis
    pts = np.array([[0.0, 0.0, 0.0], [0.3, 0.3, 0.3]])
    assert grid_cells(pts) == 55 ** 3
    assert grid_cells(pts, SurfaceFieldConfig(cell_m=0.01, reach_m=0.05)) == 41 ** 3  # 0.4 / 0.01 = 40 -> 40 + 1
    assert grid_cells(np.array([[0.0, 0, 0], [1e6, 1e6, 1e6]])) > MAX_CELLS  # no int64 overflow on a silly span


@pytest.mark.parametrize("bad", [np.zeros((0, 3)), np.full((2, 3), np.nan), np.zeros((2, 2)), "x"])
def test_grid_cells_refuses_bad_points(bad):
    with pytest.raises(CansimError):
        grid_cells(bad)


def test_the_ch6_study_warns_of_an_object_it_seldom_touched():
    from cansim.studies.ch6_active_exploration import seldom_touched

    def row(p, miss, n, thr=100.0, study="strategy", spc="on"):
        return {"presented": p, "whisks_without_contact": miss, "iterations": n, "threshold": thr, "study": study, "spc": spc}

    rows = [row("/x/flat disk.obj", 50, 60), row("/x/flat disk.obj", 20, 60), row("mug", 10, 60),
            row("/x/flat disk.obj", 60, 60, thr=300.0),  # another threshold's row of the same run: not counted again
            row("mug", 60, 60, study="spc", spc="on")]  # the SPC study's on-runs repeat strategy runs: not counted
    rows.append(row("mug", 60, 60, study="spc", spc="off"))  # the SPC study's contrast: not counted either
    lines = seldom_touched(rows)
    assert len(lines) == 1 and lines[0].startswith("the flat_disk observed a region (3 contacts or more) in only 50 of its 120")
    assert "--scale-to-m" in lines[0] and "--contact-seeking" in lines[0]
    assert "--contact-seeking" not in seldom_touched(rows, contact_seeking=True)[0]  # no advice to do what was done
    assert "--scale-to-m" not in seldom_touched([row("box_stack", 50, 60)])[0]  # a registered object: no mesh to check
    assert seldom_touched([row("mug", 30, 60)]) == []  # exactly half: not "more often than not"


def test_distinct_objects(tmp_path):
    from cansim.studies.object_options import check_distinct, object_labels

    path = tmp_path / "cup.obj"
    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(path)
    check_distinct(["mug", str(path)], ["box"])
    with pytest.raises(InvalidInputError, match="given twice"):
        check_distinct([str(path), "mug", str(tmp_path / "." / "cup.obj")])  # one file by two spellings
    with pytest.raises(InvalidInputError, match="both a library object and a novel one"):
        check_distinct(["mug", "box"], ["Mug"])  # one registered object, spelt otherwise
    with pytest.raises(InvalidInputError, match="given twice"):
        check_distinct([], ["box", "box"])
    assert object_labels(["a/cup.obj", "mug", "b/cup.stl"]) == {"a/cup.obj": "a_cup", "mug": "mug", "b/cup.stl": "b_cup"}
    assert object_labels(["a/cup.obj", "a/cup.stl"]) == {"a/cup.obj": "a_cup_obj", "a/cup.stl": "a_cup_stl"}
    assert object_labels(["cup.obj", "cup.stl", "mug"]) == {"cup.obj": "cup_obj", "cup.stl": "cup_stl", "mug": "mug"}
    assert object_labels(["x/a/cup.obj", "y/a/cup.obj", "mug"]) == {"x/a/cup.obj": "cup_1", "y/a/cup.obj": "cup_2",
                                                                    "mug": "mug"}  # the numbered fallback, clashing only
    assert object_labels(["a/Cup.obj", "b/cup.obj"]) == {"a/Cup.obj": "a_Cup", "b/cup.obj": "b_cup"}  # case aside
    labels = object_labels(["a/cup.obj", "b/cup.obj", "cup_1.obj"])
    assert len(set(labels.values())) == 3  # distinct even where a stem looks like a numbered one


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.sampled_from(["mug", "box", "cup", "duck"]),
                          st.builds(lambda d, stem, ext: f"{d}{stem}.{ext}",
                                    st.sampled_from(["", "a/", "b/", "x/a/", "y/a/", "a/b/"]),
                                    st.sampled_from(["cup", "mug", "cup_1", "My Mug"]), st.sampled_from(["obj", "stl"]))),
                max_size=8))
def test_object_labels_are_distinct_and_plain_where_nothing_clashes(specs):
    from cansim.studies.object_options import object_label, object_labels

    labels = object_labels(specs)
    assert list(labels) == list(dict.fromkeys(specs)) and len(set(labels.values())) == len(labels)
    plain = [object_label(s) for s in labels]
    if len({p.casefold() for p in plain}) == len(plain):  # no clash, case aside: the plain labels
        assert list(labels.values()) == plain


def test_a_gltf_without_an_up_axis_is_copied_once_with_its_warning(tmp_path, caplog):
    path = tmp_path / "tower.glb"
    trimesh.creation.box(extents=(0.1, 0.4, 0.1)).export(path)
    with caplog.at_level("WARNING"):
        got = conform_objects([str(path), "mug"], tmp_path / "objects")
    assert got == [str(tmp_path / "objects" / "tower.ply"), "mug"]
    assert sum("y-up by their specification" in r.getMessage() for r in caplog.records) == 1
    caplog.clear()
    with caplog.at_level("WARNING"):
        load_object(got[0])  # what the study's workers load: no warning again
    assert not caplog.records


def test_the_changes_made_are_said(tmp_path, caplog):
    _brick_mm_y_up(tmp_path / "brick.stl")
    with caplog.at_level("WARNING", logger="cansim.studies.object_options"):
        conform_objects([str(tmp_path / "brick.stl")], tmp_path / "objects", scale_to_m=0.35, up_axis="y")
    (msg,) = [r.getMessage() for r in caplog.records]
    assert "scaled by 0.001" in msg and "rotated +90 deg about x" in msg and "0.100 x 0.200 x 0.350 m" in msg


def test_whisks_to_decide_is_the_first_whisk_at_which_an_impulse_every_whisk_crosses():
    from cansim.studies.recognition import IC_THRESHOLD, whisks_to_decide
    from maps.recognition import confidence, integrated_confidence

    n = whisks_to_decide()
    ic = integrated_confidence(confidence(np.zeros(n, dtype=np.int64), 1))[:, 0]
    assert ic[n - 1] >= IC_THRESHOLD > ic[n - 2]  # one whisk fewer cannot decide
    assert whisks_to_decide(1e4) > n > whisks_to_decide(10.0)


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.sampled_from(["Box-Stack", " mug ", "duck-v2", "knot-h1", "teapot", "torus_flat-v3", ""]),
                 st.text(max_size=10)))
def test_object_name_is_the_name_resolve_object_gives_without_building(spec):
    """check_distinct compared names by building every object's mesh (1.2 s over the 53 of a full recognition run)."""
    from whisker_io.sim.catalogue import is_mesh_file, object_name, resolve_object

    if is_mesh_file(spec):
        return
    try:
        name, source = object_name(spec)
    except CansimError:
        with pytest.raises(CansimError):
            resolve_object(spec)
        return
    got = resolve_object(spec)
    assert (got.name, got.source) == (name, source)


def test_poorly_mapped_names_the_known_objects_whose_tour_seldom_observed_a_region():
    """Half the mapping whisks with 3 contacts or more is enough; fewer names the object; a map without a log is skipped."""
    from cansim.explore.explorer import KnownObject
    from cansim.studies import ch6_active_exploration

    class Mapped:  # only the mapping log: KnownObject's own counting
        mapping_observations = KnownObject.mapping_observations
        seldom_observed = KnownObject.seldom_observed

        def __init__(self, counts):
            self.mapping_log = None if counts is None else {"contacts": [None if c is None else np.zeros((c, 3))
                                                                         for c in counts]}

    sparse = Mapped([3, 2, None, 1])  # 1 of 4 observed
    half = Mapped([3, 4, None, 2])  # 2 of 4: not warned
    bare = Mapped(None)
    setup = ch6_active_exploration.Setup([sparse, half, bare], 1.0, 0.3, 0.3, objects=("capsule", "mug", "box"))
    lines = ch6_active_exploration.poorly_mapped(setup)
    assert len(lines) == 1 and "capsule observed a region in only 1 of its 4 mapping whisks" in lines[0]


@pytest.mark.parametrize("bad", [-0.1, 10.5, float("nan"), float("inf"), True, "1"])
def test_ch6_prepare_refuses_a_bad_odometry_scale_before_any_mapping(bad, monkeypatch):
    from cansim.errors import ConfigError
    from cansim.explore import explorer
    from cansim.studies import ch6_active_exploration

    def no_mapping(*a, **kw):
        raise AssertionError("mapped before the settings were checked")

    monkeypatch.setattr(explorer, "build_object_model", no_mapping)
    with pytest.raises(ConfigError, match="odometry_scale"):
        ch6_active_exploration.prepare(0, odometry_scale=bad)


_SPECS = st.one_of(st.sampled_from(["mug", "box", "cup", "duck-v2"]),
                   st.builds(lambda d, stem, ext: f"{d}{stem}.{ext}", st.sampled_from(["", "a/", "b/", "x/a/", "y/a/"]),
                             st.sampled_from(["cup", "Cup", "mug", "cup_1", "My Mug", "a_cup"]), st.sampled_from(["obj", "stl"])))


@settings(max_examples=200, deadline=None)
@given(st.lists(_SPECS, min_size=1, max_size=8))
def test_labels_are_distinct_file_stems_that_name_each_object_once(specs):
    from whisker_io.sim.catalogue import object_file_names, object_labels

    labels = object_labels(specs)
    assert len({lab.casefold() for lab in labels.values()}) == len(labels) == len(set(specs))
    assert all(lab and all(c.isalnum() or c in "-_" for c in lab) for lab in labels.values())  # a file's stem
    assert object_file_names(specs) == [labels[s] for s in specs]  # the map files are named by the labels


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(_SPECS, st.one_of(st.just(""), _SPECS)), min_size=1, max_size=6))
def test_labelled_rows_name_objects_by_label_and_their_mesh_files(pairs):
    from cansim.studies.object_options import labelled_rows
    from whisker_io.sim.catalogue import object_labels

    rows = [{"presented": p, "decision": d, "whisks": i} for i, (p, d) in enumerate(pairs)]
    kept = [dict(r) for r in rows]
    labels = object_labels([s for pair in pairs for s in pair if s])
    out = labelled_rows(rows, labels, ("presented", "decision"), of="presented")
    assert rows == kept  # the study's own rows are not changed
    inverse = {lab: spec for spec, lab in labels.items()}
    for r, (p, d) in zip(out, pairs):
        assert inverse[r["presented"]] == p and (r["decision"] == "" if d == "" else inverse[r["decision"]] == d)
        assert r["mesh_file"] == (os.path.abspath(p) if is_mesh_file(p) else "")
        assert os.path.isabs(r["mesh_file"]) or r["mesh_file"] == ""
    with pytest.raises(KeyError):  # an object the labels do not know is a bug, not a silent raw name
        labelled_rows([{"presented": "teapot", "decision": ""}], labels, ("presented",), of="presented")


# ------------------------------------------------------------------ one value per mesh file (a folder of downloads)
from cansim.studies.object_options import check_mesh_options, per_mesh_file  # noqa: E402


def test_one_value_per_mesh_file_in_their_order():
    specs = ["mug", "a.obj", "duck-v2", "b.glb"]
    assert per_mesh_file(specs, None, "--up-axis") == [None] * 4
    assert per_mesh_file(specs, "y", "--up-axis") == [None, "y", None, "y"]
    assert per_mesh_file(specs, ["y"], "--up-axis") == [None, "y", None, "y"]
    assert per_mesh_file(specs, ["z", "y"], "--up-axis") == [None, "z", None, "y"]
    assert per_mesh_file(specs, [0.35, 0.2], "--scale-to-m") == [None, 0.35, None, 0.2]
    with pytest.raises(InvalidInputError, match=r"--up-axis takes one value for every mesh file or one per mesh file, "
                                                r"in their order \(2 here: a, b\); got 3"):
        per_mesh_file(specs, ["z", "y", "x"], "--up-axis")
    with pytest.raises(InvalidInputError, match="one per mesh file"):
        check_mesh_options(specs, scale_to_m=[0.3, 0.3, 0.3])


_SPEC = st.one_of(st.sampled_from(["mug", "box", "duck-v1", "torus_flat"]),
                  st.builds(lambda n, e: f"{n}{e}", st.sampled_from(["a", "b", "c d"]), st.sampled_from([".obj", ".STL", ".glb"])))


@given(st.lists(_SPEC, max_size=6), st.lists(st.floats(0.05, 2.0), min_size=1, max_size=6))
@settings(max_examples=80, deadline=None)
def test_per_mesh_file_places_the_values_on_the_files_or_refuses(specs, values):
    files = [i for i, s in enumerate(specs) if is_mesh_file(s)]
    if len(values) not in (1, len(files)):
        with pytest.raises(InvalidInputError, match=f"{len(files)} here"):
            per_mesh_file(specs, values, "--scale-to-m")
        return
    out = per_mesh_file(specs, values, "--scale-to-m")
    assert len(out) == len(specs)
    assert [i for i, v in enumerate(out) if v is not None] == files
    assert [out[i] for i in files] == (values * len(files) if len(values) == 1 else values)


def test_a_y_up_glb_and_a_z_up_stl_in_one_run_each_stand_upright(tmp_path):
    # the same 0.16 x 0.16 x 0.36 m block: the STL z-up, the GLB y-up (its 0.36 along y)
    trimesh.creation.box(extents=(0.16, 0.16, 0.36)).export(tmp_path / "tall.stl")
    trimesh.creation.box(extents=(0.16, 0.36, 0.16)).export(tmp_path / "tall.glb")
    out = conform_objects([str(tmp_path / "tall.stl"), "mug", str(tmp_path / "tall.glb")], tmp_path / "objects",
                          up_axis=["z", "y"])
    assert out[1] == "mug"
    for path in (out[0], out[2]):
        assert np.allclose(sorted(trimesh.load(path).extents), [0.16, 0.16, 0.36], atol=1e-6)
        assert trimesh.load(path).extents[2] == pytest.approx(0.36, abs=1e-6)  # upright, both
    # one value for both lays the STL on its side
    out = conform_objects([str(tmp_path / "tall.stl"), str(tmp_path / "tall.glb")], tmp_path / "objects2", up_axis="y")
    assert trimesh.load(out[0]).extents[2] == pytest.approx(0.16, abs=1e-6)


@pytest.mark.parametrize("module", ["cansim.studies.ch5_object_maps", "cansim.studies.ch6_active_exploration",
                                    "cansim.studies.recognition"])
def test_the_studies_take_a_value_per_mesh_file(module, tmp_path):
    import importlib

    main = importlib.import_module(module).main
    with pytest.raises(InvalidInputError, match=r"--up-axis takes one value for every mesh file or one per mesh file"):
        trimesh.creation.box(extents=(0.2, 0.2, 0.3)).export(tmp_path / "a.obj")
        trimesh.creation.box(extents=(0.2, 0.3, 0.2)).export(tmp_path / "b.obj")
        main(["--quick", "--no-progress", "--out", str(tmp_path / "out"), "--objects", str(tmp_path / "a.obj"),
              str(tmp_path / "b.obj"), "--up-axis", "z", "y", "x"])


def test_the_ch6_study_says_first_when_a_narrower_object_stands_inside_the_believed_volume(tmp_path):
    from cansim.studies.ch6_active_exploration import seldom_touched

    path = tmp_path / "capsule.obj"
    trimesh.creation.box(extents=(0.16, 0.16, 0.36)).export(path)
    row = {"presented": str(path), "whisks_without_contact": 300, "iterations": 300, "threshold": 100.0,
           "study": "strategy", "spc": "on"}
    wide = trimesh.creation.box(extents=(0.26, 0.24, 0.36))  # 5 cm beyond its sides in x, 4 in y
    (line,) = seldom_touched([row], believed=wide)
    advice = line.split("; ", 1)[1]
    assert advice.startswith("it is 0.16 x 0.16 m across, the believed volume (the known objects' common box) "
                             "0.26 x 0.24 m: the search places the array before that volume, up to 5 cm from this "
                             "object's sides, beyond most whiskers' reach; --contact-seeking moves the array")
    assert line.count("--contact-seeking") == 1
    (line,) = seldom_touched([row], believed=trimesh.creation.box(extents=(0.24, 0.24, 0.36)))  # 4 cm: within reach
    assert "believed volume" not in line and "--contact-seeking" in line
    (line,) = seldom_touched([row], contact_seeking=True, believed=wide)  # it was on: nothing to advise of it
    assert "believed volume" not in line and "--contact-seeking" not in line


def test_a_negative_up_axis_stands_in_a_list_as_one_word():
    from whisker_io.command_line import CommandParser

    ap = CommandParser(prog="x")
    ap.add_argument("--objects", nargs="+")
    add_mesh_options(ap, per_file=True)
    a = ap.parse_args(["--objects", "a.stl", "mug", "b.glb", "--up-axis=z,-y"])
    assert per_mesh_file(a.objects, a.up_axis, "--up-axis") == ["z", None, "-y"]
    assert per_mesh_file(["a.stl", "b.glb"], "-y", "--up-axis") == ["-y", "-y"]
