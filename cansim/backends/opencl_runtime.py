"""Find OpenCL runtimes installed from PyPI and register them with the ICD loader.

pyopencl's wheels ship an OpenCL ICD loader that finds PoCL (the ``opencl`` extra)
by itself. PoCL 3.0 of ``pocl-binary-distribution`` cannot compile for CPUs its
LLVM 14 does not know (e.g. AMD Zen 5: "unknown target CPU 'generic'"). Intel's CPU
OpenCL runtime (the ``opencl-intel`` extra: ``intel-opencl-rt`` and
``intel-cmplr-lib-rt``) works there, but installs ``<prefix>/lib/libintelocl.so``
without telling any ICD loader about it.

:func:`register_icds` does that step: when the Intel runtime is installed and the
user has not pointed the loader elsewhere (``OCL_ICD_VENDORS`` unset), it writes a
vendors directory holding one ``.icd`` file per runtime (the Intel library and every
``.icd`` of the system directory ``/etc/OpenCL/vendors``, so that system drivers stay
visible) and sets ``OCL_ICD_VENDORS`` to it. That must happen before the loader first
lists platforms, so :mod:`cansim.backends.opencl_backend` calls it before it imports
pyopencl. The directory is ``<prefix>/etc/OpenCL/cansim-vendors`` (``<prefix>`` is
``sys.prefix``, the virtual environment) when that is writable, else
``$XDG_CACHE_HOME/cansim/OpenCL/vendors`` (default ``~/.cache``).

Environment variables:

* ``OCL_ICD_VENDORS`` - set by the user: cansim leaves the ICD set-up alone.
* ``CANSIM_OPENCL_ICD=0`` - do not register anything.

This module imports neither pyopencl nor numpy.
"""

from __future__ import annotations

import logging
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from whisker_io.persistence import write_atomically

__all__ = ["IcdRegistration", "find_intel_cpu_runtime", "register_icds", "INTEL_PLATFORM_NAME"]

log = logging.getLogger(__name__)

#: platform name reported by Intel's CPU runtime
INTEL_PLATFORM_NAME = "Intel(R) OpenCL"
#: environment variable that turns the automatic registration off when "0"
OPT_OUT_ENV_VAR = "CANSIM_OPENCL_ICD"
_SYSTEM_VENDORS = Path("/etc/OpenCL/vendors")
_INTEL_LIBRARY = "libintelocl.so"


@dataclass(frozen=True)
class IcdRegistration:
    """What :func:`register_icds` did.

    Attributes
    ----------
    vendors_dir : str or None
        The directory ``OCL_ICD_VENDORS`` now points to (None: nothing registered).
    intel_library : str or None
        Path of the Intel CPU runtime found (None: not installed).
    reason : str
        One sentence: what was registered, or why nothing was.
    """

    vendors_dir: Optional[str]
    intel_library: Optional[str]
    reason: str


def _prefixes() -> list[Path]:
    seen: list[Path] = []
    for p in (sys.prefix, sys.base_prefix, _user_base()):
        if p and Path(p) not in seen:
            seen.append(Path(p))
    return seen


def _user_base() -> Optional[str]:
    try:
        import site

        return site.getuserbase()
    except Exception:  # pragma: no cover - site always exists in CPython
        return None


def find_intel_cpu_runtime() -> Optional[Path]:
    """Path of Intel's CPU OpenCL runtime installed from PyPI (``<prefix>/lib/libintelocl.so``), or None.

    Looks in the running environment's prefix, the base interpreter's prefix and the
    user's site base (``pip install --user``), in that order.
    """
    for prefix in _prefixes():
        lib = prefix / "lib" / _INTEL_LIBRARY
        if lib.is_file():
            return lib
    return None


def _vendors_dir_candidates() -> list[Path]:
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return [Path(sys.prefix) / "etc" / "OpenCL" / "cansim-vendors", Path(cache) / "cansim" / "OpenCL" / "vendors"]


def _write_if_changed(path: Path, text: str) -> None:
    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except OSError:
        pass
    write_atomically(path, lambda fh: fh.write(text.encode("utf-8")))


def _icd_files(intel_lib: Path) -> dict[str, str]:
    """File name -> contents of the vendors directory (Intel plus the system's ICDs)."""
    files = {"intel-cpu.icd": f"{intel_lib}\n"}
    try:
        system = sorted(_SYSTEM_VENDORS.glob("*.icd"))
    except OSError:
        system = []
    for icd in system:
        try:
            text = icd.read_text(encoding="utf-8")
        except OSError:
            continue
        if _INTEL_LIBRARY in text:
            continue  # the same runtime, already listed
        files[f"system-{icd.name}"] = text if text.endswith("\n") else text + "\n"
    return files


def register_icds() -> IcdRegistration:
    """Register an installed Intel CPU OpenCL runtime with the ICD loader (idempotent).

    Sets ``OCL_ICD_VENDORS`` for this process (and its children) to a directory
    cansim writes; call it before pyopencl first lists platforms. Does nothing when
    ``OCL_ICD_VENDORS`` is already set, when ``CANSIM_OPENCL_ICD=0``, or when the Intel
    runtime is not installed. Never raises: a directory that cannot be written is
    reported in the returned :class:`IcdRegistration`.

    Returns
    -------
    IcdRegistration
    """
    intel = find_intel_cpu_runtime()
    intel_s = str(intel) if intel else None
    if os.environ.get(OPT_OUT_ENV_VAR, "").strip() == "0":
        return IcdRegistration(None, intel_s, f"${OPT_OUT_ENV_VAR}=0: no OpenCL runtime registered by cansim")
    if intel is None:
        return IcdRegistration(
            None, None, 'Intel\'s CPU OpenCL runtime is not installed (pip install "cansim[opencl-intel]")'
        )
    current = os.environ.get("OCL_ICD_VENDORS")
    candidates = _vendors_dir_candidates()
    if current and Path(current) not in candidates:
        return IcdRegistration(
            current, intel_s, f"$OCL_ICD_VENDORS={current} was set by the user; cansim registered nothing"
        )
    files = _icd_files(intel)
    errors = []
    for vendors in candidates:
        try:
            vendors.mkdir(parents=True, exist_ok=True)
            for name, text in files.items():
                _write_if_changed(vendors / name, text)
            for stale in vendors.glob("*.icd"):
                if stale.name not in files:
                    stale.unlink()
        except OSError as exc:
            errors.append(f"{vendors}: {exc}")
            continue
        if "pyopencl" in sys.modules:
            log.debug("registering OpenCL ICDs after pyopencl was imported; a loader that already "
                      "listed its platforms will not see them")
        os.environ["OCL_ICD_VENDORS"] = str(vendors)
        log.debug("registered Intel's CPU OpenCL runtime %s via OCL_ICD_VENDORS=%s", intel, vendors)
        return IcdRegistration(str(vendors), intel_s, f"registered {intel} in {vendors}")
    return IcdRegistration(None, intel_s, "could not write an OpenCL vendors directory: " + "; ".join(errors))
