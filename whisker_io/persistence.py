"""Reading the library's ``.npz`` save files (no pickle) with typed errors."""

from __future__ import annotations

import os
import zipfile

import numpy as np

from whisker_io.errors import CorruptFileError

__all__ = ["read_npz"]


def read_npz(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """All members of an ``.npz`` archive written by a ``save()`` of this library.

    Raises
    ------
    CorruptFileError
        The file is missing, empty, truncated, not an ``.npz`` archive (or one of a zip
        version or compression this Python cannot read), or a member is damaged.
    """
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as exc:
        # NotImplementedError: zipfile's answer to a zip version or compression it cannot read
        raise CorruptFileError(f"cannot be read as an .npz archive ({exc})", path=path) from exc
    if not hasattr(archive, "files"):
        raise CorruptFileError("holds a single array, not an .npz archive", path=path)
    with archive:
        try:
            return {k: archive[k] for k in archive.files}
        except Exception as exc:  # zip/CRC/header errors of a damaged member
            raise CorruptFileError(f"damaged archive member ({exc})", path=path) from exc
