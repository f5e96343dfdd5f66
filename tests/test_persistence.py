"""whisker_io.persistence.read_npz: every unreadable archive is a CorruptFileError (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest

from whisker_io.persistence import read_npz
from whisker_io.errors import CorruptFileError


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
