"""OpenCL-specific behaviour of the opencl backend (its numerics are also proven by the
conformance suite): device discovery and choice, missing platforms, float64 on devices
without fp64, the fused step against the numpy reference, and the program cache.

Discovery tests run against fake platforms and need no OpenCL device; the others are
skipped when no device here can build the kernels.
"""

from __future__ import annotations

import numpy as np
import pytest

cl = pytest.importorskip("pyopencl")

from cansim.backends import opencl_backend as ob  # noqa: E402
from cansim.backends.numpy_backend import NumpyBackend  # noqa: E402
from cansim.errors import BackendUnavailableError, InvalidInputError  # noqa: E402
from cansim.kernels import gaussian_kernel_1d  # noqa: E402
from cansim.population import Population  # noqa: E402

CPU, GPU = int(cl.device_type.CPU), int(cl.device_type.GPU)


class FakeDevice:
    def __init__(self, name, type_=CPU, version="OpenCL 3.0", fp64=True):
        self.name = name
        self.type = type_
        self.version = version
        self.double_fp_config = 63 if fp64 else 0
        self.extensions = "cl_khr_fp64" if fp64 else ""
        self.max_work_group_size = 1024


class FakePlatform:
    def __init__(self, name, devices):
        self.name = name
        self._devices = devices

    def get_devices(self):
        if not self._devices:
            raise cl.RuntimeError("clGetDeviceIDs failed: DEVICE_NOT_FOUND")
        return self._devices


@pytest.fixture
def fake_platforms(monkeypatch):
    """Install fake platforms; ``cl.Context`` fails so any real OpenCL work is caught."""
    monkeypatch.delenv(ob.DEVICE_ENV_VAR, raising=False)

    def no_context(*args, **kwargs):
        raise AssertionError("a context was created")

    monkeypatch.setattr(cl, "Context", no_context)

    def install(*platforms):
        monkeypatch.setattr(cl, "get_platforms", lambda: list(platforms))

    return install


# ------------------------------------------------------------------ discovery (no device)
def test_no_platform_names_the_extra(monkeypatch, fake_platforms):
    fake_platforms()
    with pytest.raises(BackendUnavailableError, match=r'cansim\[opencl\]'):
        ob.OpenCLBackend()

    def loader_error():
        raise cl.LogicError("clGetPlatformIDs failed: PLATFORM_NOT_FOUND_KHR")

    monkeypatch.setattr(cl, "get_platforms", loader_error)
    with pytest.raises(BackendUnavailableError, match=r'cansim\[opencl\]'):
        ob.OpenCLBackend()


def test_platform_without_devices_names_the_extra(fake_platforms):
    fake_platforms(FakePlatform("Empty", []))
    with pytest.raises(BackendUnavailableError, match=r'cansim\[opencl\]'):
        ob.OpenCLBackend()


def test_construction_creates_no_context(fake_platforms):
    fake_platforms(FakePlatform("P", [FakeDevice("cpu0")]))
    backend = ob.OpenCLBackend()  # the fixture's Context raises if it were called
    assert backend.name == "opencl"


def test_default_prefers_a_gpu_then_platform_order(fake_platforms):
    cpu, gpu = FakeDevice("cpu0"), FakeDevice("gpu0", GPU)
    fake_platforms(FakePlatform("A", [cpu]), FakePlatform("B", [gpu]))
    assert ob.OpenCLBackend()._candidates == [gpu, cpu]


def test_device_by_index_and_name_from_env_and_argument(monkeypatch, fake_platforms):
    d00, d01, d10 = FakeDevice("alpha"), FakeDevice("beta"), FakeDevice("Gamma Card", GPU)
    fake_platforms(FakePlatform("A", [d00, d01]), FakePlatform("B", [d10]))
    monkeypatch.setenv(ob.DEVICE_ENV_VAR, "0:1")
    assert ob.OpenCLBackend()._candidates == [d01]
    monkeypatch.setenv(ob.DEVICE_ENV_VAR, "gamma")  # case-insensitive name substring
    assert ob.OpenCLBackend()._candidates == [d10]
    assert ob.OpenCLBackend(device="A / alpha")._candidates == [d00]  # argument beats env
    assert ob.OpenCLBackend(device=" 1 : 0 ")._candidates == [d10]


@pytest.mark.parametrize("spec", ["2:0", "0:7", "no such device"])
def test_unknown_device_lists_the_available_ones(monkeypatch, fake_platforms, spec):
    fake_platforms(FakePlatform("A", [FakeDevice("alpha")]))
    monkeypatch.setenv(ob.DEVICE_ENV_VAR, spec)
    with pytest.raises(BackendUnavailableError, match=r"0:0 A / alpha") as err:
        ob.OpenCLBackend()
    assert ob.DEVICE_ENV_VAR in str(err.value)


def test_pocl_without_cpu_model_is_passed_over(fake_platforms):
    generic = FakeDevice("pthread-cpu", version="OpenCL 3.0 PoCL HSTR: pthread-x86_64-unknown-linux-gnu-generic")
    known = FakeDevice("pthread-cpu", version="OpenCL 3.0 PoCL HSTR: pthread-x86_64-unknown-linux-gnu-znver3")
    fake_platforms(FakePlatform("PoCL", [generic]))
    with pytest.raises(BackendUnavailableError, match="does not recognise the CPU"):
        ob.OpenCLBackend()
    with pytest.raises(BackendUnavailableError, match="does not recognise the CPU"):
        ob.OpenCLBackend(device="0:0")
    fake_platforms(FakePlatform("PoCL", [generic]), FakePlatform("Other", [known]))
    assert ob.OpenCLBackend()._candidates == [known]


def test_fp64_required_on_a_device_without_it(fake_platforms):
    fake_platforms(FakePlatform("P", [FakeDevice("half-card", GPU, fp64=False)]))
    with pytest.raises(BackendUnavailableError, match="float64"):
        ob.OpenCLBackend(device="0:0", fp64=True)


def test_work_group_must_be_a_power_of_two(fake_platforms):
    fake_platforms(FakePlatform("P", [FakeDevice("cpu0")]))
    with pytest.raises(InvalidInputError, match="power of two"):
        ob.OpenCLBackend(work_group=48)


# ------------------------------------------------------------------ on a real device
@pytest.fixture(scope="module")
def device_label():
    """Label of the device a default backend uses; skips when none builds the kernels."""
    try:
        backend = ob.OpenCLBackend()
        backend.prepare(np.float32)
    except BackendUnavailableError as exc:
        pytest.skip(f"no usable OpenCL device: {exc}")
    return next(label for label, d in ob.list_devices() if d == backend.device)


@pytest.fixture
def backend(device_label, monkeypatch):
    monkeypatch.delenv(ob.DEVICE_ENV_VAR, raising=False)
    return ob.OpenCLBackend(device=device_label.split(" ", 1)[0])


def _close(got, ref, dtype):
    tol = 1e-5 if np.dtype(dtype) == np.float32 else 1e-12
    ref = np.asarray(ref, dtype=np.float64)
    np.testing.assert_allclose(np.asarray(got, dtype=np.float64), ref, rtol=tol, atol=tol * np.abs(ref).max())


def _packet(shape, dtype, seed):
    """A random 3-cell-wide packet (wrapped) normalised to sum 1, and the rng."""
    rng = np.random.default_rng(seed)
    mask = np.zeros(shape, dtype=bool)
    mask[np.ix_(*[(np.arange(-1, 2) + rng.integers(n)) % n for n in shape])] = True
    a = np.where(mask, rng.random(shape), 0.0)
    return (a / a.sum()).astype(dtype), rng


def test_device_from_env_var_is_used(device_label, monkeypatch):
    monkeypatch.setenv(ob.DEVICE_ENV_VAR, device_label.split(" ", 1)[0])
    backend = ob.OpenCLBackend()
    assert f"{backend.device.name.strip()}" in device_label


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize(
    "shape, shift_axes",
    [((3, 4, 5, 3, 2, 4), (0, 1, 2)), ((9, 7, 12), (0, 1)), ((360,), None), ((4, 5, 6, 7), (0, 1, 2, 3))],
)
def test_fused_step_equals_reference(backend, dtype, shape, shift_axes):
    """Injection (repeated indices), dynamics (taps longer than an axis), conditional
    shift with more than one cell per step, uniform shift and decoding in one call."""
    ref = NumpyBackend()
    a, rng = _packet(shape, dtype, seed=sum(shape))
    nd = len(shape)
    exc = [gaussian_kernel_1d(7, 1.0) for _ in range(nd)]
    inh = [gaussian_kernel_1d(5, 2.0) for _ in range(nd)]
    cond = None
    if shift_axes is not None:
        cond_shape = tuple(n for i, n in enumerate(shape) if i not in shift_axes)
        cond = rng.uniform(-2.5, 2.5, cond_shape + (len(shift_axes),))
    flat = np.array([0, 5, 5, a.size - 1])
    kw = dict(
        flat_index=flat, values=np.array([0.1, 0.02, 0.03, 0.2]), exc=exc, inh=inh, phi=2e-5,
        shift_axes=shift_axes, cond_shifts=cond, uniform_shifts=rng.uniform(-1.7, 1.7, nd), window=3,
    )
    before = a.copy()
    want, want_pos = ref.step(a, **kw)
    out = np.full(shape, -1.0, dtype=dtype)
    got, got_pos = backend.step(a, out=out, **kw)
    np.testing.assert_array_equal(a, before)
    assert got is out and got.dtype == np.dtype(dtype)
    _close(got, want, dtype)
    np.testing.assert_allclose(got_pos, want_pos, atol=1e-4 if dtype == np.float32 else 1e-9)
    assert abs(got.sum(dtype=np.float64) - 1.0) < 1e-5


def test_collapse_reports_none_and_leaves_out_alone(backend):
    a = np.full((5, 6), 1e-6, dtype=np.float32)  # below phi after the kernels
    out = np.full_like(a, 7.0)
    taps = [gaussian_kernel_1d(3, 1.0)] * 2
    assert backend.dynamics(a, taps, taps, 1e-3, out=out) is None
    kw = dict(flat_index=None, values=None, exc=taps, inh=taps, phi=1e-3, shift_axes=None,
              cond_shifts=None, uniform_shifts=np.array([0.5, 0.0]), window=3)
    assert backend.step(a, out=out, **kw) == (None, None)
    assert np.all(out == 7.0)


def test_single_precision_accumulators(device_label):
    """fp64=False emulates a device without fp64: float64 grids are refused with a
    clear error, float32 grids still match the float64 reference to 1e-5."""
    backend = ob.OpenCLBackend(device=device_label.split(" ", 1)[0], fp64=False)
    a64, _ = _packet((6, 7, 8), np.float64, seed=3)
    taps = [gaussian_kernel_1d(7, 1.0)] * 3
    with pytest.raises(BackendUnavailableError, match="dtype=float32"):
        backend.dynamics(a64, taps, taps, 2e-5)
    a32 = a64.astype(np.float32)
    _close(backend.dynamics(a32, taps, taps, 2e-5), NumpyBackend().dynamics(a32, taps, taps, 2e-5), np.float32)


def test_program_is_built_once_per_dtype(backend, monkeypatch):
    a = np.ones((4, 4), dtype=np.float32) / 16
    taps = [np.array([1.0])] * 2
    backend.dynamics(a, taps, taps, 0.0)
    assert set(backend.build_seconds) == {"float32"}

    def no_build(*args, **kwargs):
        raise AssertionError("the program was rebuilt")

    monkeypatch.setattr(cl, "Program", no_build)
    np.testing.assert_allclose(backend.shift(a, np.array([0.5, 1.0])), a, rtol=1e-6)  # uniform stays uniform


def test_population_runs_on_opencl(device_label, monkeypatch):
    """A 3-D RatSLAM population moves like the numpy one over 30 fused steps."""
    monkeypatch.setenv(ob.DEVICE_ENV_VAR, device_label.split(" ", 1)[0])
    pops = [Population.openratslam(backend=name) for name in ("numpy", "opencl")]
    for pop in pops:
        pop.reset_gaussian([10, 10, 9], 1.0)
        for _ in range(30):
            pos = pop.step(velocity=0.3, omega=0.02, dt=1.0)
    np.testing.assert_allclose(pos, pops[0].decode(), atol=1e-4)
    _close(pops[1].activity, pops[0].activity, np.float32)


def test_circular_cover_finds_the_shortest_wrapped_interval():
    occupied = np.zeros(10, dtype=bool)
    occupied[[8, 9, 0, 2]] = True  # cells 8..2 across the wrap: start 8, length 5
    assert ob._circular_cover(occupied) == (8, 5)
    occupied[:] = False
    occupied[4] = True
    assert ob._circular_cover(occupied) == (4, 1)
    assert ob._circular_cover(np.ones(6, dtype=bool))[1] == 6


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_locality_window_equals_whole_grid(device_label, dtype):
    """A packet near the wrap of a 61 x 61 x 36 grid with an injection beside it: the step
    on the window the packet can reach equals the whole-grid step and the reference."""
    shape = (61, 61, 36)
    a = np.zeros(shape)
    a[np.ix_([59, 60, 0], [30, 31], [35, 0, 1])] = np.arange(1, 19).reshape(3, 2, 3)
    a = (a / a.sum()).astype(dtype)
    rng = np.random.default_rng(7)
    exc = [gaussian_kernel_1d(7, 1.0)] * 3
    inh = [gaussian_kernel_1d(5, 2.0)] * 3
    kw = dict(
        flat_index=np.array([np.ravel_multi_index((1, 32, 2), shape)] * 2), values=np.array([0.05, 0.01]),
        exc=exc, inh=inh, phi=2e-5, shift_axes=(0, 1), cond_shifts=rng.uniform(-2.5, 2.5, (36, 2)),
        uniform_shifts=np.array([0.0, 0.0, -1.3]), window=3,
    )
    assert ob._locality_window(a, kw["flat_index"], exc, inh, (0, 1), kw["cond_shifts"], kw["uniform_shifts"])
    label = device_label.split(" ", 1)[0]
    local, pos_local = ob.OpenCLBackend(device=label).step(a, **kw)
    whole, pos_whole = ob.OpenCLBackend(device=label, locality=False).step(a, **kw)
    want, want_pos = NumpyBackend().step(a, **kw)
    _close(local, whole, dtype)  # equal up to the order of the one global sum
    _close(local, want, dtype)
    np.testing.assert_allclose(pos_local, want_pos, atol=1e-9)
    np.testing.assert_allclose(pos_local, pos_whole, atol=1e-9)
