"""Truthful backends: available_backends() lists what can run, backend_status() says why not.

Also the ICD registration of Intel's CPU OpenCL runtime (cansim.backends.opencl_runtime)
and the fallback to it where PoCL cannot build.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cansim
import cansim.backends as reg
from cansim.backends import opencl_runtime
from cansim.errors import CansimError, InvalidInputError, UnknownBackendError

ROOT = Path(__file__).resolve().parents[1]


def test_status_covers_every_registered_backend_and_numpy_runs():
    status = reg.backend_status()
    assert set(status) == set(reg.registered_backends())
    for usable, reason in status.values():
        assert isinstance(usable, bool) and isinstance(reason, str) and reason
    assert status["numpy"][0] is True
    assert cansim.available_backends()[0] == "numpy"


def test_available_backends_are_exactly_the_usable_ones_and_each_constructs():
    status = reg.backend_status()
    avail = reg.available_backends()
    assert set(avail) == {name for name, (ok, _) in status.items() if ok}
    for name in avail:
        assert reg.get_backend(name).name == name


def test_status_is_cached_until_refresh(monkeypatch):
    reg.backend_status()  # fills the cache if no earlier call did
    calls = []
    real = reg._probe
    monkeypatch.setattr(reg, "_probe", lambda name: calls.append(name) or real(name))
    reg.backend_status()
    reg.backend_status()
    assert calls == []  # answered from the cache
    reg.backend_status(refresh=True)
    assert sorted(calls) == sorted(reg.registered_backends())


def test_missing_dependency_is_reported_with_the_extra_to_install(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(reg.importlib.util, "find_spec", lambda n, *a: None if n == "pyopencl" else real(n, *a))
    try:
        status = reg.backend_status(refresh=True)
        assert status["opencl"][0] is False
        assert 'cansim[opencl]' in status["opencl"][1]
        assert "opencl" not in reg.available_backends()
    finally:
        monkeypatch.undo()
        reg.backend_status(refresh=True)


def test_a_probe_that_crashes_is_reported_not_raised(monkeypatch):
    def boom(backend):
        raise RuntimeError("driver exploded")

    monkeypatch.setitem(reg._PROBES, "numba", boom)
    try:
        usable, reason = reg.backend_status(refresh=True)["numba"]
        assert usable is False and "RuntimeError" in reason and "driver exploded" in reason
        assert "numba" not in reg.available_backends()
    finally:
        monkeypatch.undo()
        reg.backend_status(refresh=True)


@settings(max_examples=50, deadline=None)
@given(st.one_of(st.integers(), st.text(max_size=5), st.none(), st.floats(allow_nan=True)))
def test_backend_status_refresh_must_be_a_bool(value):
    with pytest.raises(InvalidInputError):
        reg.backend_status(refresh=value)


@settings(max_examples=100, deadline=None)
@given(st.one_of(st.text(max_size=12), st.integers(), st.none(), st.binary(max_size=4)))
def test_get_backend_with_any_unknown_name_raises_a_typed_error(name):
    if name in reg.registered_backends():
        return
    with pytest.raises(UnknownBackendError) as info:
        reg.get_backend(name)
    assert isinstance(info.value, CansimError) and "choose one of" in str(info.value)


# ------------------------------------------------------------------ ICD registration
def _fake_runtime(tmp_path: Path, monkeypatch) -> Path:
    lib = tmp_path / "prefix" / "lib" / "libintelocl.so"
    lib.parent.mkdir(parents=True)
    lib.write_bytes(b"")
    vendors = tmp_path / "vendors"
    monkeypatch.setattr(opencl_runtime, "find_intel_cpu_runtime", lambda: lib)
    monkeypatch.setattr(opencl_runtime, "_vendors_dir_candidates", lambda: [vendors])
    monkeypatch.setattr(opencl_runtime, "_SYSTEM_VENDORS", tmp_path / "etc-vendors")
    monkeypatch.delenv("OCL_ICD_VENDORS", raising=False)
    monkeypatch.delenv(opencl_runtime.OPT_OUT_ENV_VAR, raising=False)
    return lib


def test_register_icds_writes_the_runtime_path_and_points_the_loader_at_it(tmp_path, monkeypatch):
    lib = _fake_runtime(tmp_path, monkeypatch)
    system = tmp_path / "etc-vendors"
    system.mkdir()
    (system / "gpu.icd").write_text("/usr/lib/libgpu.so\n")
    reg_ = opencl_runtime.register_icds()
    vendors = tmp_path / "vendors"
    assert reg_.vendors_dir == str(vendors) and os.environ["OCL_ICD_VENDORS"] == str(vendors)
    assert (vendors / "intel-cpu.icd").read_text() == f"{lib}\n"
    assert (vendors / "system-gpu.icd").read_text() == "/usr/lib/libgpu.so\n"  # system drivers stay visible
    # idempotent, and a second call with the variable it set itself still registers
    assert opencl_runtime.register_icds().vendors_dir == str(vendors)
    assert sorted(p.name for p in vendors.iterdir()) == ["intel-cpu.icd", "system-gpu.icd"]


def test_register_icds_respects_the_users_loader_settings_and_the_opt_out(tmp_path, monkeypatch):
    _fake_runtime(tmp_path, monkeypatch)
    monkeypatch.setenv("OCL_ICD_VENDORS", str(tmp_path / "mine"))
    r = opencl_runtime.register_icds()
    assert os.environ["OCL_ICD_VENDORS"] == str(tmp_path / "mine") and "set by the user" in r.reason
    assert not (tmp_path / "vendors").exists()
    monkeypatch.delenv("OCL_ICD_VENDORS")
    monkeypatch.setenv(opencl_runtime.OPT_OUT_ENV_VAR, "0")
    r = opencl_runtime.register_icds()
    assert r.vendors_dir is None and "OCL_ICD_VENDORS" not in os.environ


def test_register_icds_without_the_runtime_does_nothing(monkeypatch):
    monkeypatch.setattr(opencl_runtime, "find_intel_cpu_runtime", lambda: None)
    monkeypatch.delenv("OCL_ICD_VENDORS", raising=False)
    monkeypatch.delenv(opencl_runtime.OPT_OUT_ENV_VAR, raising=False)
    r = opencl_runtime.register_icds()
    assert r.vendors_dir is None and "opencl-intel" in r.reason and "OCL_ICD_VENDORS" not in os.environ


def test_register_icds_reports_an_unwritable_directory(tmp_path, monkeypatch):
    _fake_runtime(tmp_path, monkeypatch)
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setattr(opencl_runtime, "_vendors_dir_candidates", lambda: [blocker / "sub"])
    r = opencl_runtime.register_icds()
    assert r.vendors_dir is None and "could not write" in r.reason and "OCL_ICD_VENDORS" not in os.environ


_FALLBACK = r"""
import numpy as np
import cansim.backends.opencl_backend as ob
from cansim import Population
real = ob._unusable_reason
# pretend PoCL cannot compile for this CPU, as PoCL 3.0 on AMD Zen 5
ob._unusable_reason = lambda d: "pretend" if "Portable Computing Language" in d.platform.name else real(d)
b = ob.OpenCLBackend()
b.prepare(np.float32)
print(b.device.platform.name.strip())
ref = Population.openratslam(backend="numpy")
ocl = Population.openratslam(backend=b)
for _ in range(5):
    ref.step(velocity=0.3, omega=0.1, dt=1.0)
    ocl.step(velocity=0.3, omega=0.1, dt=1.0)
print(float(np.abs(ref.activity - ocl.activity).max()))
"""


@pytest.mark.skipif(importlib.util.find_spec("pyopencl") is None, reason="pyopencl is not installed")
@pytest.mark.skipif(
    opencl_runtime.find_intel_cpu_runtime() is None,
    reason='Intel\'s CPU OpenCL runtime is not installed (pip install "cansim[opencl-intel]")',
)
def test_without_pocl_the_registered_intel_runtime_is_found_by_itself():
    env = {k: v for k, v in os.environ.items() if k not in ("OCL_ICD_VENDORS", "CANSIM_OPENCL_DEVICE", "CANSIM_OPENCL_ICD")}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    proc = subprocess.run([sys.executable, "-c", _FALLBACK], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    platform, diff = proc.stdout.strip().splitlines()[-2:]
    assert platform == opencl_runtime.INTEL_PLATFORM_NAME
    assert float(diff) <= 1e-6  # same dynamics as the numpy reference


def test_ring_example_refuses_an_unusable_backend_in_one_line(monkeypatch, capsys):
    import importlib.util as iu

    spec = iu.spec_from_file_location("ring_attractor_example", ROOT / "examples" / "ring_attractor.py")
    mod = iu.module_from_spec(spec)
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "backend_status", lambda: {"opencl": (False, "no OpenCL platform")})
    assert mod.main(["--backend", "opencl", "--steps", "5"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "cannot run here: no OpenCL platform" in err


@pytest.mark.skipif(importlib.util.find_spec("pyopencl") is None, reason="pyopencl is not installed")
def test_the_runtime_cansim_registered_comes_after_the_others(monkeypatch):
    import cansim.backends.opencl_backend as ob

    class Dev:
        def __init__(self, name, gpu=False):
            self.name, self.version = name, "OpenCL 3.0"
            self.type = ob.cl.device_type.GPU if gpu else ob.cl.device_type.CPU

    intel, pocl, gpu = Dev("xeon"), Dev("pthread-xeon"), Dev("card", gpu=True)
    listing = [("0:0 Intel(R) OpenCL / xeon", intel), ("1:0 Portable Computing Language / pthread-xeon", pocl),
               ("2:0 Vendor GPU / card", gpu)]
    monkeypatch.setattr(ob, "list_devices", lambda: listing)
    monkeypatch.delenv(ob.DEVICE_ENV_VAR, raising=False)
    monkeypatch.setattr(ob, "ICD_REGISTRATION", opencl_runtime.IcdRegistration("/x", "/x/libintelocl.so", "test"))
    assert ob._select_devices(None) == ([gpu, pocl, intel], False)
    # not registered by cansim (e.g. a system install): plain platform order
    monkeypatch.setattr(ob, "ICD_REGISTRATION", opencl_runtime.IcdRegistration(None, None, "test"))
    assert ob._select_devices(None) == ([gpu, intel, pocl], False)
