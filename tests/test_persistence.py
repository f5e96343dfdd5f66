"""whisker_io.persistence.read_npz: every unreadable archive is a CorruptFileError (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from whisker_io.persistence import read_npz
from whisker_io.errors import CorruptFileError, InvalidInputError


def _patched(tmp_path, offset_in_record: int, value: bytes, signature: bytes = b"PK\x01\x02"):
    path = tmp_path / "m.npz"
    np.savez(path, a=np.arange(3))
    raw = bytearray(path.read_bytes())
    at = raw.index(signature) + offset_in_record
    raw[at:at + len(value)] = value
    path.write_bytes(bytes(raw))
    return path


def test_a_good_archive_reads_back(tmp_path):
    path = tmp_path / "m.npz"
    np.savez(path, a=np.arange(3), b=np.eye(2))
    got = read_npz(path)
    assert set(got) == {"a", "b"} and got["a"].tolist() == [0, 1, 2]


def test_an_unsupported_zip_version_is_a_corrupt_file(tmp_path):
    # central directory record: bytes 6-7 are "version needed to extract"; 9.9 is beyond any zipfile
    path = _patched(tmp_path, 6, (99).to_bytes(2, "little"))
    with pytest.raises(CorruptFileError, match="zip file version"):
        read_npz(path)


def test_an_unsupported_compression_method_is_a_corrupt_file(tmp_path):
    # bytes 10-11 of the central directory record and 8-9 of the local header: the compression method
    path = _patched(tmp_path, 10, (97).to_bytes(2, "little"))
    raw = bytearray(path.read_bytes())
    raw[8:10] = (97).to_bytes(2, "little")
    path.write_bytes(bytes(raw))
    with pytest.raises(CorruptFileError):
        read_npz(path)


def test_a_damaged_archive_in_memory_is_a_corrupt_file_named_by_its_type():
    """Models save to and load from open files (io.BytesIO); a damaged one raised TypeError from
    the error's own constructor (os.fspath of a BytesIO) instead of CorruptFileError."""
    import io

    buf = io.BytesIO()
    np.savez(buf, a=np.arange(3))
    with pytest.raises(CorruptFileError, match="<BytesIO>: cannot be read"):
        read_npz(io.BytesIO(buf.getvalue()[:20]))


def test_a_missing_file_a_folder_and_a_pickle_say_what_they_are(tmp_path):
    with pytest.raises(CorruptFileError, match="no such file; check the path"):
        read_npz(tmp_path / "nope.npz")
    with pytest.raises(CorruptFileError, match="a folder, not a file"):
        read_npz(tmp_path)
    path = tmp_path / "pickled.npy"
    np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(CorruptFileError, match="pickled objects, which are never loaded") as info:
        read_npz(path)
    assert "allow_pickle" not in str(info.value)  # numpy's advice to load it unsafely is not passed on
    text = tmp_path / "box.obj"
    text.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")  # a mesh given where a saved map was asked for
    with pytest.raises(CorruptFileError, match="not an .npz archive") as info:
        read_npz(text)
    assert "pickle" not in str(info.value)
    member = tmp_path / "member.npz"
    np.savez(member, ok=np.arange(2), obj=np.array([{"a": 1}], dtype=object))  # an archive with an object member
    with pytest.raises(CorruptFileError, match="pickled objects, which are never loaded") as info:
        read_npz(member)
    assert "allow_pickle" not in str(info.value) and "damaged" not in str(info.value)


def test_a_name_without_npz_saves_and_loads_by_the_same_name(tmp_path):
    """``slam.save("noext")`` wrote ``noext.npz`` (numpy's rule) and ``RatSLAM.load("noext")`` said "no such file"
    (a user's pass, session 47); an ExperienceMap likewise."""
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig
    from maps.experience_map import ExperienceMap

    slam = RatSLAM(RatSLAMConfig(frontend="ids"))
    for k in range(5):
        slam.step(0.1, 0.05, 1.0, k % 3)
    slam.save(tmp_path / "noext")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["noext.npz"]  # no temporary file left behind
    for name in ("noext", "noext.npz"):
        back = RatSLAM.load(tmp_path / name)
        assert back.experience_map.n_experiences == slam.experience_map.n_experiences
        np.testing.assert_array_equal(back.pose_cells.activity, slam.pose_cells.activity)
    slam.experience_map.save(str(tmp_path / "map"))
    assert ExperienceMap.load(str(tmp_path / "map")).n_experiences == slam.experience_map.n_experiences
    with pytest.raises(CorruptFileError, match="no such file"):
        read_npz(tmp_path / "other")  # neither the name nor the name with .npz


def test_an_interrupted_save_keeps_the_earlier_file(tmp_path, monkeypatch):
    """A save that fails half-way leaves the previous file under its name, whole (written beside it, then renamed)."""
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig

    slam = RatSLAM(RatSLAMConfig(frontend="ids"))
    slam.step(0.1, 0.0, 1.0, 0)
    slam.save(tmp_path / "run.npz")
    before = (tmp_path / "run.npz").read_bytes()
    slam.step(0.1, 0.0, 1.0, 1)

    def broken_savez(fh, **arrays):
        fh.write(b"PK\x03\x04 half an archive")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        slam.save(tmp_path / "run.npz")
    assert (tmp_path / "run.npz").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]  # the half-written temporary file removed
    monkeypatch.undo()
    assert RatSLAM.load(tmp_path / "run.npz").iteration == 1


def test_a_file_of_the_other_kind_is_named_not_called_corrupt(tmp_path):
    """A whole model loaded as a map, or a map as a model, said "the file is corrupt" (a user's pass, session 47)."""
    from cansim.models.ratslam import RatSLAM, RatSLAMConfig
    from cansim.models.whisker_ratslam import WhiskerRatSLAM
    from maps.experience_map import ExperienceMap

    slam = RatSLAM(RatSLAMConfig(frontend="ids"))
    slam.step(0.1, 0.0, 1.0, 0)
    slam.save(tmp_path / "model.npz")
    slam.experience_map.save(tmp_path / "map.npz")
    with pytest.raises(CorruptFileError, match="holds a whole model") as exc:
        ExperienceMap.load(tmp_path / "model.npz")
    assert "corrupt" not in str(exc.value)
    for cls in (RatSLAM, WhiskerRatSLAM):
        with pytest.raises(CorruptFileError, match="holds an experience map") as exc:
            cls.load(tmp_path / "map.npz")
        assert "corrupt" not in str(exc.value)
    with pytest.raises(CorruptFileError, match="corrupt"):  # a map file missing a field of its own is still corrupt
        arrays = dict(np.load(tmp_path / "map.npz"))
        del arrays["link_ends"], arrays["format"]
        np.savez(tmp_path / "broken.npz", **arrays)
        ExperienceMap.load(tmp_path / "broken.npz")


def test_npz_path_follows_numpy_and_leaves_open_files_alone(tmp_path):
    import io

    from whisker_io.persistence import npz_path

    assert npz_path("run") == "run.npz" and npz_path("run.npz") == "run.npz" and npz_path(tmp_path / "a.b") == str(tmp_path / "a.b.npz")
    buf = io.BytesIO()
    assert npz_path(buf) is buf


def test_a_save_writes_through_a_link_and_keeps_the_files_permissions(tmp_path):
    import os
    import stat

    from whisker_io.persistence import write_npz

    real = tmp_path / "data" / "run.npz"
    real.parent.mkdir()
    write_npz(real, {"a": np.zeros(2)})
    os.chmod(real, 0o640)
    link = tmp_path / "run.npz"
    link.symlink_to(real)
    write_npz(link, {"a": np.ones(3)})
    assert link.is_symlink() and np.array_equal(read_npz(link)["a"], np.ones(3))
    assert stat.S_IMODE(real.stat().st_mode) == 0o640
    assert sorted(p.name for p in real.parent.iterdir()) == ["run.npz"]  # no temporary file left
    fresh = tmp_path / "new.npz"
    write_npz(fresh, {"a": np.zeros(1)})
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~umask  # as open() makes a file, not mkstemp's 0600


def test_writing_into_a_folder_that_does_not_exist_names_the_folder(tmp_path):
    """The radial model's own atomic write named its temporary file "x.skops.tmp" here (a user's pass, session 47);
    every save now writes through one mechanism, write_atomically."""
    from whisker_io.persistence import write_atomically, write_npz

    for write in (lambda p: write_npz(p, {"a": np.zeros(1)}), lambda p: write_atomically(p, lambda fh: fh.write(b"x"))):
        with pytest.raises(FileNotFoundError) as exc:
            write(tmp_path / "absent" / "x.npz")
        assert exc.value.filename == str(tmp_path / "absent")
    assert list(tmp_path.iterdir()) == []


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(first=st.binary(max_size=300), second=st.binary(max_size=300), fail_after=st.booleans())
def test_write_atomically_replaces_whole_or_not_at_all(tmp_path, first, second, fail_after):
    from whisker_io.persistence import write_atomically

    path = tmp_path / "f.bin"
    write_atomically(path, lambda fh: fh.write(first))
    assert path.read_bytes() == first

    def half_then_fail(fh):
        fh.write(second[: len(second) // 2])
        raise RuntimeError("interrupted")

    if fail_after:
        with pytest.raises(RuntimeError):
            write_atomically(path, half_then_fail)
        assert path.read_bytes() == first  # the earlier file, whole
    else:
        write_atomically(path, lambda fh: fh.write(second))
        assert path.read_bytes() == second
    assert [p.name for p in tmp_path.iterdir()] == ["f.bin"]  # no temporary file left


def test_the_bytes_and_the_rename_reach_the_disk_before_write_atomically_returns(tmp_path, monkeypatch):
    """The temporary file is fsynced before it takes the name, the folder after: a power cut cannot leave the
    name on an empty file."""
    import os

    from whisker_io.persistence import write_atomically

    events: list[tuple[str, str]] = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd):
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        return real_fsync(fd)

    def replace(src, dst):
        events.append(("replace", os.fspath(dst)))
        return real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    write_atomically(tmp_path / "f.bin", lambda fh: fh.write(b"abc"))
    assert (tmp_path / "f.bin").read_bytes() == b"abc"
    kinds = [k for k, _ in events]
    assert kinds == ["fsync", "replace", "fsync"]
    assert events[0][1].endswith(".tmp") and events[1][1] == str(tmp_path / "f.bin") and events[2][1] == str(tmp_path)


def _saveable(kind: str):
    """One small object of each class that saves, and the class that loads it."""
    from cansim import Axis, Population, RatSLAM
    from cansim.spiking import SpikingPopulation
    from maps.experience_map import ExperienceMap

    if kind == "RatSLAM":
        return RatSLAM(backend="numpy", xy_cells=9, heading_cells=12, cell_size_m=0.1), RatSLAM
    if kind == "ExperienceMap":
        return ExperienceMap(), ExperienceMap
    if kind == "Population":
        return Population([Axis.angle("th", 12)], backend="numpy"), Population
    if kind == "SpikingPopulation":
        return SpikingPopulation([Axis.angle("th", 12)], backend="numpy"), SpikingPopulation
    from cansim.explore.explorer import KnownObject
    from cansim.models.whisker_ratslam import WhiskerRatSLAM

    model = WhiskerRatSLAM(backend="numpy")
    if kind == "KnownObject":
        return KnownObject("thing", model, 0, 0, 0), KnownObject
    from test_roundtrip_properties import _library_and_table  # two small object maps appended

    library = _library_and_table()[1]
    return library, type(library)


@pytest.mark.parametrize("kind", ["RatSLAM", "ExperienceMap", "Population", "SpikingPopulation", "KnownObject",
                                  "ObjectLibrary"])
def test_every_save_names_its_file_as_numpy_does_and_loads_by_the_name_given(tmp_path, kind):
    """save("state") writes state.npz whatever the class (numpy's rule); load("state") and load("state.npz") read it."""
    obj, cls = _saveable(kind)
    obj.save(tmp_path / "state")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.npz"]
    for name in ("state", "state.npz"):
        assert type(cls.load(tmp_path / name)) is type(obj)
    obj.save(str(tmp_path / "other.npz"))  # a name with .npz keeps it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.npz", "state.npz"]


def test_an_object_library_or_a_radial_model_given_as_a_model_is_named_with_the_file(tmp_path):
    """An ObjectLibrary.save file or a .skops file given where a model goes (a robot lab's --map, session 48) was
    "field 'model': missing; the file is corrupt ..." with that sentence twice and no file named."""
    import zipfile

    from cansim.explore.explorer import KnownObject
    from cansim.models.whisker_ratslam import WhiskerRatSLAM

    library, _ = _saveable("ObjectLibrary")
    library.save(tmp_path / "library.npz")
    with zipfile.ZipFile(tmp_path / "svr10.skops", "w") as z:  # what skops writes: a zip with schema.json
        z.writestr("schema.json", '{"__class__": "SVR"}')
    for cls in (WhiskerRatSLAM, KnownObject):
        with pytest.raises(CorruptFileError) as exc:
            cls.load(tmp_path / "library.npz")
        assert str(exc.value).startswith(f"{tmp_path / 'library.npz'}: this file holds an object library")
        assert "ObjectLibrary.load" in str(exc.value) and "corrupt" not in str(exc.value)
        with pytest.raises(CorruptFileError) as exc:
            cls.load(tmp_path / "svr10.skops")
        assert str(exc.value).startswith(f"{tmp_path / 'svr10.skops'}: this file is a scikit-learn model")


def test_a_models_load_error_names_the_file_and_says_corrupt_once(tmp_path):
    from cansim.models.ratslam import RatSLAM

    RatSLAM(backend="numpy", xy_cells=9, heading_cells=12, cell_size_m=0.1).save(tmp_path / "m.npz")
    arrays = dict(np.load(tmp_path / "m.npz"))
    del arrays["model"]
    np.savez(tmp_path / "broken.npz", **arrays)
    with pytest.raises(CorruptFileError) as exc:
        RatSLAM.load(tmp_path / "broken.npz")
    assert exc.value.path == str(tmp_path / "broken.npz") and exc.value.field == "model"
    assert str(exc.value).count("the file is corrupt") == 1


@pytest.mark.parametrize("fmt", [np.int64(2), np.int64(0), np.int64(-5), np.float64(1.0), np.array([1])])
def test_a_model_file_of_another_layout_is_refused(tmp_path, fmt):
    from cansim.models.ratslam import RatSLAM

    slam = RatSLAM(backend="numpy", xy_cells=9, heading_cells=12, cell_size_m=0.1)
    slam.save(tmp_path / "m.npz")
    arrays = dict(np.load(tmp_path / "m.npz"))
    arrays["loop_format"] = fmt
    np.savez(tmp_path / "other.npz", **arrays)
    with pytest.raises(CorruptFileError, match="field 'loop_format': layout .*this version reads 1"):
        RatSLAM.load(tmp_path / "other.npz")
    del arrays["loop_format"]  # a file without it has this layout
    np.savez(tmp_path / "plain.npz", **arrays)
    assert RatSLAM.load(tmp_path / "plain.npz").iteration == slam.iteration


def test_an_older_file_under_the_bare_name_beside_the_npz_is_ambiguous_not_read_silently(tmp_path):
    """save("ring") writes ring.npz; an older save wrote ring: load("ring") read the older one (review, s48)."""
    from cansim import Axis, Population

    old = Population([Axis.angle("th", 12)], backend="numpy")
    with open(tmp_path / "ring", "wb") as fh:  # what a save before this version wrote under the bare name
        old.save(fh)
    new = Population([Axis.angle("th", 16)], backend="numpy")  # another size: which file was read shows
    new.save(tmp_path / "ring")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ring", "ring.npz"]
    with pytest.raises(InvalidInputError, match="ring.npz exist, and a save"):
        Population.load(tmp_path / "ring")
    assert Population.load(tmp_path / "ring.npz").shape == new.shape  # the full name is never ambiguous
    (tmp_path / "ring.npz").unlink()
    assert Population.load(tmp_path / "ring").shape == old.shape  # an older file alone still loads
    # not ambiguous: a folder of that name beside the .npz, or a link to it
    (tmp_path / "ring").unlink()
    new.save(tmp_path / "ring")
    (tmp_path / "ring").mkdir()
    assert Population.load(tmp_path / "ring").shape == new.shape
    (tmp_path / "ring").rmdir()
    (tmp_path / "ring").symlink_to(tmp_path / "ring.npz")
    assert Population.load(tmp_path / "ring").shape == new.shape


def test_a_new_file_follows_the_umask_of_the_moment(tmp_path):
    import os
    import stat

    from whisker_io.persistence import write_atomically

    before = os.umask(0o027)
    try:
        write_atomically(tmp_path / "f.bin", lambda fh: fh.write(b"x"))
        assert stat.S_IMODE((tmp_path / "f.bin").stat().st_mode) == 0o640
        assert os.umask(0o027) == 0o027  # and the umask was left as it was
    finally:
        os.umask(before)


@settings(max_examples=40, deadline=None)
@given(problem=st.text(min_size=1, max_size=20), field=st.one_of(st.none(), st.text(min_size=1, max_size=8)),
       named=st.booleans())
def test_naming_file_names_the_file_once_and_keeps_the_cause(problem, field, named):
    from whisker_io.persistence import naming_file

    original = CorruptFileError(problem, field=field, path="first.npz" if named else None)
    with pytest.raises(CorruptFileError) as exc:
        with naming_file("model.npz"):
            raise original
    if named:  # it names a file already: raised as it was
        assert exc.value is original
    else:
        assert exc.value.path == "model.npz" and exc.value.field == field and exc.value.__cause__ is original
        assert str(exc.value).startswith("model.npz: ") and str(exc.value).count("model.npz") == 1
    with pytest.raises(KeyError):  # anything else passes through untouched
        with naming_file("model.npz"):
            raise KeyError("x")


@pytest.mark.parametrize("description", ["[]", "null", '"x"', "3"])
def test_a_model_description_that_is_no_json_object_is_a_corrupt_file(tmp_path, description):
    from cansim.models.ratslam import RatSLAM

    RatSLAM(backend="numpy", xy_cells=9, heading_cells=12, cell_size_m=0.1).save(tmp_path / "m.npz")
    arrays = dict(np.load(tmp_path / "m.npz"))
    arrays["model"] = np.array(description)
    np.savez(tmp_path / "odd.npz", **arrays)
    with pytest.raises(CorruptFileError, match="field 'model': not a model description"):
        RatSLAM.load(tmp_path / "odd.npz")


# ------------------------------------------------------------------ write_csv: a study's table, whole or not at all
_CELL = st.one_of(st.text(max_size=12), st.integers(-10**6, 10**6), st.booleans())


@given(st.lists(st.fixed_dictionaries({"a": _CELL, "b c": _CELL, "d": _CELL}), max_size=8))
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_write_csv_reads_back_as_written(tmp_path, rows):
    import csv

    from whisker_io.persistence import write_csv

    path = tmp_path / "t.csv"
    write_csv(path, ("a", "b c", "d"), rows)
    with open(path, newline="", encoding="utf-8") as fh:
        back = list(csv.DictReader(fh))
    assert [list(r) for r in back] == [["a", "b c", "d"]] * len(rows)
    assert back == [{k: str(v) for k, v in r.items()} for r in rows]


def test_write_csv_with_a_bad_row_leaves_the_earlier_table(tmp_path):
    from whisker_io.persistence import write_csv

    path = tmp_path / "t.csv"
    write_csv(path, ("x", "y"), [{"x": 1, "y": 2}])
    assert path.read_bytes() == b"x,y\r\n1,2\r\n"  # csv's own line ends, by hand
    with pytest.raises(ValueError, match="fields not in fieldnames"):
        write_csv(path, ("x", "y"), [{"x": 3, "y": 4}, {"x": 5, "z": 6}])
    assert path.read_bytes() == b"x,y\r\n1,2\r\n" and [p.name for p in tmp_path.iterdir()] == ["t.csv"]
