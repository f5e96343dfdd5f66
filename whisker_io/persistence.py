"""The library's ``.npz`` save files (no pickle): written whole or not at all, read with typed errors."""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
import zipfile
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, BinaryIO, Callable, Mapping

import numpy as np

from whisker_io.errors import CorruptFileError, InvalidInputError

__all__ = ["naming_file", "npz_path", "read_npz", "sync_folder", "write_atomically", "write_csv", "write_npz"]


_PICKLED = "holds pickled objects, which are never loaded (they can run code): not a file a save() here wrote"


def _is_pickle(path: Any) -> bool:
    """Whether the file at ``path`` is a pickle or an .npy of objects, by its first bytes (False for an open file or
    an unreadable one)."""
    if not isinstance(path, (str, os.PathLike)):
        return False
    try:
        with open(path, "rb") as fh:
            head = fh.read(6)
    except OSError:
        return False
    return head[:1] == b"\x80" or head == b"\x93NUMPY"  # a pickle's protocol marker, the .npy magic


def npz_path(path: str | os.PathLike[str] | BinaryIO) -> str | os.PathLike[str] | BinaryIO:
    """Where :func:`numpy.savez` writes ``path``: with ``.npz`` added when its name lacks it (``"run"`` ->
    ``"run.npz"``); a path that has it, or an open file, is returned unchanged."""
    if not isinstance(path, (str, os.PathLike)) or os.fspath(path).endswith(".npz"):
        return path
    return os.fspath(path) + ".npz"


def read_npz(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """All members of an ``.npz`` archive written by a ``save()`` of this library.

    A ``path`` that names no file but whose :func:`npz_path` does is read from there: a
    model saved as ``save("run")`` (numpy writes ``run.npz``) loads as ``load("run")``. When
    both ``run`` and ``run.npz`` exist the name is ambiguous (an older save wrote ``run``):
    that is an error naming both, never the older file read silently.

    Raises
    ------
    CorruptFileError
        The file is missing, empty, truncated, not an ``.npz`` archive (or one of a zip
        version or compression this Python cannot read), or a member is damaged.
    InvalidInputError
        The name is ambiguous (above).
    """
    if isinstance(path, (str, os.PathLike)) and npz_path(path) != path and os.path.isfile(npz_path(path)):
        if os.path.isfile(path) and not os.path.samefile(path, npz_path(path)):
            # an older file under the bare name beside what save() writes now: which one?
            raise InvalidInputError(f"{os.fspath(path)}: both this file and {os.fspath(npz_path(path))} exist, and a "
                                    "save() to this name writes the .npz one; load the one you mean by its full name")
        if not os.path.isfile(path):  # no file of that name (or a folder): the .npz save() wrote
            path = npz_path(path)
    if isinstance(path, (str, os.PathLike)) and not os.path.isfile(path):
        what = "a folder, not a file" if os.path.isdir(path) else "no such file"
        raise CorruptFileError(f"{what}; check the path", path=path)
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as exc:
        # NotImplementedError: zipfile's answer to a zip version or compression it cannot read
        if isinstance(exc, ValueError) and "pickle" in str(exc):
            # numpy takes any file that is no zip or .npy for a pickle, and would suggest loading it unsafely
            if _is_pickle(path):
                raise CorruptFileError(_PICKLED, path=path) from exc
            raise CorruptFileError("not an .npz archive (a save() here writes a zip of arrays): check that this is "
                                   "the file you meant", path=path) from exc
        raise CorruptFileError(f"cannot be read as an .npz archive ({exc})", path=path) from exc
    if not hasattr(archive, "files"):
        raise CorruptFileError("holds a single array, not an .npz archive", path=path)
    with archive:
        try:
            return {k: archive[k] for k in archive.files}
        except Exception as exc:  # zip/CRC/header errors of a damaged member, or an object member
            if isinstance(exc, ValueError) and "pickle" in str(exc):  # numpy's message would suggest loading it unsafely
                raise CorruptFileError(_PICKLED, path=path) from exc
            raise CorruptFileError(f"damaged archive member ({exc})", path=path) from exc


@contextlib.contextmanager
def naming_file(path: str | os.PathLike[str] | Any) -> Iterator[None]:
    """Within the block, a :class:`CorruptFileError` that names no file is raised again naming ``path`` (chained to
    the original, whose traceback says where it was met): for a loader that read a file's arrays first and
    rebuilds its object from them."""
    try:
        yield
    except CorruptFileError as exc:
        located = exc.located(path)
        if located is exc:
            raise
        raise located from exc


def write_npz(path: str | os.PathLike[str] | BinaryIO, arrays: Mapping[str, Any]) -> None:
    """Write ``arrays`` as an ``.npz`` archive (no pickle) where :func:`numpy.savez` would: at
    :func:`npz_path` of ``path`` (``"run"`` -> ``run.npz``), which :func:`read_npz` finds again.

    A file name is written by :func:`write_atomically` (whole or not at all, through a link,
    keeping the file's permissions); an open binary file (e.g. ``io.BytesIO``) is written as is.
    Every ``save()`` of the library writes through here, so all name their files alike.
    """
    if not isinstance(path, (str, os.PathLike)):
        np.savez(path, **arrays)
        return
    write_atomically(npz_path(path), lambda fh: np.savez(fh, **arrays))


def write_atomically(path: str | os.PathLike[str], write: Callable[[BinaryIO], object]) -> None:
    """Let ``write`` fill a file that then replaces ``path`` whole: never half a file under that name.

    ``write`` gets a binary file: a temporary file of its own beside ``path`` (two writers never
    share one), renamed over it (``os.replace``) once written. A symbolic link is written through
    (it stays a link) and an existing file keeps its permissions (a new one gets those
    :func:`open` would give it). The bytes are flushed to the disk (``os.fsync``) before the
    rename, and the folder after it. A failed or interrupted ``write`` leaves the earlier file and no temporary one.

    Raises
    ------
    FileNotFoundError
        ``path``'s folder does not exist (named).
    """
    target = os.path.realpath(path)  # through a symbolic link, as np.savez writes: the link stays a link
    folder = os.path.dirname(target)
    if not os.path.isdir(folder):
        raise FileNotFoundError(errno.ENOENT, "no such folder to write into", folder)
    mode = os.stat(target).st_mode & 0o7777 if os.path.exists(target) else _new_file_mode()
    fd, tmp = tempfile.mkstemp(dir=folder, prefix="." + os.path.basename(target) + ".", suffix=".tmp")  # one per writer
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())  # on the disk before it takes the name: a power cut leaves the old file or the new
        os.chmod(tmp, mode)  # the file's own permissions (a new one's as open() would give it), not mkstemp's 0600
        os.replace(tmp, target)
        sync_folder(folder)  # the rename itself on the disk
    except BaseException:  # a failed or interrupted write leaves the earlier file and no temporary one
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def write_csv(path: str | os.PathLike[str], columns: Sequence[str], rows: Iterable[Mapping[str, Any]]) -> None:
    """``rows`` as a CSV file with a header of ``columns`` (:class:`csv.DictWriter`), written whole or not at all
    (:func:`write_atomically`): a study's table never ends half-written, whatever stops it.

    Raises
    ------
    ValueError
        A row with a key outside ``columns`` (as :class:`csv.DictWriter`); nothing is written.
    FileNotFoundError
        ``path``'s folder does not exist.
    """
    import csv
    import io

    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=list(columns))
    w.writeheader()
    w.writerows(rows)
    data = buf.getvalue().encode("utf-8")
    write_atomically(path, lambda fh: fh.write(data))


def sync_folder(folder: str | os.PathLike[str]) -> None:
    """Flush a folder's entries (names made, renamed or removed in it) to the disk; a no-op where folders
    cannot be opened."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover - platforms without folder descriptors
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - file systems that refuse it
        pass
    finally:
        os.close(fd)


def _new_file_mode() -> int:
    """The permissions :func:`open` gives a new file here: 0666 less the process' umask.

    Read from ``/proc/self/status`` where there is one (Linux): setting the umask to read it
    back would change it for every thread of the process for a moment."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    umask = os.umask(0)  # elsewhere: the only portable way to read it
    os.umask(umask)
    return 0o666 & ~umask
