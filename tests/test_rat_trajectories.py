"""cansim.studies.rat_trajectories: recorded rat paths (ratinabox's data) drive the attractors.

Truths used: the recordings' own sampling (Sargolini 50 Hz in a 1 m box), the integral of
the derived velocity against the path, the movement direction against the velocity, a
random walk's variance for the odometry noise, and the recorded path itself for the
decoded estimates. The headline (re-anchoring through learnt LV -> attractor weights
lowers the drift of the rate ring, the spiking ring and the rate sheet) is asserted on the
quick run of the installed entry point (seeds 0 and 1, the tuning seeds; the held-out seed 2
and window are measured in the module docstring).
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cansim.errors import CansimError, InvalidInputError
from cansim.spiking import SpikingPopulation, spiking_params_from_rate
from cansim.studies import rat_trajectories as rt


def _has_ratinabox() -> bool:
    try:
        import ratinabox  # noqa: F401
    except ImportError:
        return False
    return True


needs_data = pytest.mark.skipif(not _has_ratinabox(), reason="ratinabox (extra 'rat') is not installed")


@pytest.fixture(scope="module")
def sargolini_60s():
    return rt.load_trajectory("sargolini", duration_s=60.0)


# ------------------------------------------------------------------ the data
def test_missing_package_is_a_typed_error_that_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "ratinabox", None)  # import ratinabox -> ModuleNotFoundError
    with pytest.raises(rt.TrajectoryDataUnavailableError, match=r'pip install "cansim\[rat\]"') as info:
        rt.load_trajectory("sargolini")
    assert isinstance(info.value, CansimError) and isinstance(info.value, ImportError)


@needs_data
def test_start_s_gives_the_later_window_of_the_recording(sargolini_60s):
    later = rt.load_trajectory("sargolini", duration_s=60.0, start_s=30.0)
    assert later.time_s[0] == 0.0 and later.n_samples == sargolini_60s.n_samples
    # the window from 30 s is the first minute's second half (both on the recording's 50 Hz clock)
    np.testing.assert_allclose(later.position_m[:1500], sargolini_60s.position_m[1500:3000], atol=1e-9)
    with np.load(rt._data_file("sargolini")) as data:  # the recording itself: its position at t0 + 30 s
        t, pos = data["t"], data["pos"]
    expected = [np.interp(t[0] + 30.0, t, pos[:, k]) for k in range(2)]
    np.testing.assert_allclose(later.position_m[0], expected, atol=1e-12)


@needs_data
@pytest.mark.parametrize("start", [-1.0, float("nan"), 1e6, "300"])
def test_a_bad_start_is_a_typed_error(start):
    with pytest.raises(InvalidInputError, match="start_s"):
        rt.load_trajectory("sargolini", start_s=start)


def test_unknown_trajectory_is_refused():
    with pytest.raises(InvalidInputError, match="sargolini"):
        rt.load_trajectory("morris_water_maze")


@needs_data
def test_sargolini_is_50_hz_in_a_one_metre_box(sargolini_60s):
    t = sargolini_60s
    assert t.dt_s == pytest.approx(0.02, abs=1e-9)
    assert t.n_samples == 3001 and t.duration_s == pytest.approx(60.0)
    lo, hi = t.arena_m
    assert np.all(lo >= -0.01) and np.all(hi <= 1.01)
    assert np.isfinite(t.velocity_m_s).all() and np.isfinite(t.angular_velocity_rad_s).all()


@needs_data
def test_velocity_integrates_to_the_path_and_heading_is_its_direction(sargolini_60s):
    t = sargolini_60s
    from scipy.integrate import cumulative_trapezoid

    path = t.position_m[0] + cumulative_trapezoid(t.velocity_m_s, dx=t.dt_s, axis=0, initial=0.0)
    # the velocity is the smoothed path's: the integral stays within a few cm of the raw recording
    assert np.max(np.linalg.norm(path - t.position_m, axis=1)) < 0.05
    speed = np.linalg.norm(t.velocity_m_s, axis=1)
    fast = speed > 0.2
    direction = np.arctan2(t.velocity_m_s[fast, 1], t.velocity_m_s[fast, 0])
    diff = np.angle(np.exp(1j * (t.heading_rad[fast] - direction)))
    assert np.median(np.abs(np.degrees(diff))) < 10.0
    # the angular velocity is the heading's derivative
    turned = np.sum(t.angular_velocity_rad_s) * t.dt_s
    assert turned == pytest.approx(t.heading_rad[-1] - t.heading_rad[0], abs=0.2)


@needs_data
def test_odometry_noise_is_a_random_walk_of_the_stated_diffusion(sargolini_60s):
    t = sargolini_60s
    p = rt.check_params({"odometry_gain_error": 0.0, "heading_diffusion_rad_per_sqrt_s": 0.1,
                         "position_diffusion_m_per_sqrt_s": 0.02})
    omega, vel = rt.noisy_odometry(t, p, seed=3)
    # per-sample noise s.d. = D / sqrt(dt): its integral over one second has s.d. D (within 5 % on 3000 samples)
    assert np.std((omega - t.angular_velocity_rad_s) * math.sqrt(t.dt_s)) == pytest.approx(0.1, rel=0.05)
    assert np.std((vel - t.velocity_m_s) * math.sqrt(t.dt_s)) == pytest.approx(0.02, rel=0.05)
    exact = rt.check_params({"odometry_gain_error": 0.0, "heading_diffusion_rad_per_sqrt_s": 0.0,
                             "position_diffusion_m_per_sqrt_s": 0.0})
    omega0, vel0 = rt.noisy_odometry(t, exact, seed=3)
    assert np.array_equal(omega0, t.angular_velocity_rad_s) and np.array_equal(vel0, t.velocity_m_s)
    again = rt.noisy_odometry(t, p, seed=3)
    assert np.array_equal(again[0], omega)  # deterministic for a seed


# -------------------------------------------------------------- the attractors
EXACT = {"odometry_gain_error": 0.0, "heading_diffusion_rad_per_sqrt_s": 0.0, "position_diffusion_m_per_sqrt_s": 0.0,
         "anchoring": False}


@needs_data
def test_rate_ring_follows_the_recorded_heading_from_exact_odometry(sargolini_60s):
    r = rt.simulate(sargolini_60s, {**EXACT, "model": "rate_ring"}, 0)
    assert r.unit == "deg" and r.error.shape == (sargolini_60s.n_samples,)
    assert r.rms_error < 3.0  # a 1-deg ring integrating the true turning for a minute


@needs_data
def test_rate_sheet_follows_the_recorded_path_from_exact_odometry(sargolini_60s):
    r = rt.simulate(sargolini_60s, {**EXACT, "model": "rate_sheet"}, 0)
    assert r.unit == "m"
    # a minute of exact odometry on 2 cm cells: the packet stays within a few cm of the rat
    assert r.rms_error < 0.04
    assert r.decoded[0] == pytest.approx(sargolini_60s.position_m[0], abs=0.05)


@needs_data
def test_noisy_odometry_drifts(sargolini_60s):
    exact = rt.simulate(sargolini_60s, {**EXACT, "model": "rate_ring"}, 0)
    noisy = rt.simulate(sargolini_60s, {"model": "rate_ring", "anchoring": False}, 0)
    assert noisy.drift_per_min > 3 * exact.drift_per_min


@needs_data
def test_anchoring_learns_one_view_per_landmark_on_the_sheet(sargolini_60s):
    r = rt.simulate(sargolini_60s, {"model": "rate_sheet", "anchoring": True}, 0)
    assert 1 <= r.n_views <= len(rt.LANDMARK_FRACTIONS)
    assert r.anchor_samples > 0


def test_drift_per_minute_is_the_slope_through_the_origin():
    t = np.linspace(0.0, 120.0, 241)
    run = rt.DriftRun("rate_ring", False, t, np.zeros_like(t), np.zeros_like(t), 3.0 * t / 60.0, "deg")
    assert run.drift_per_min == pytest.approx(3.0)
    assert run.rms_error == pytest.approx(math.sqrt(np.mean((3.0 * t / 60.0) ** 2)))


def test_a_view_onset_pulse_at_the_default_current_moves_the_spiking_packet_to_its_template():
    """The spiking ring's re-anchoring, alone: a packet at cell 100, then for ``spiking_inject_s`` the
    current ``spiking_inject_current * template / max(template)`` with the template a learnt one (the
    packet's 50 ms spike counts) rolled 90 cells away. At the default current the packet is at
    the template 0.3 s later (the truth: cell 190); at 10 threshold units (below the measured
    threshold of ~25, the far cells' global inhibition) it stays at 100."""
    from cansim.axes import Axis
    from cansim.spiking import SpikeCountDecoder

    p = rt.check_params({})
    axes = (Axis.angle("heading", p["ring_cells"]),)
    prm = spiking_params_from_rate(rt._ring_params(p))  # the ring's network (no turning here: no lead calibration)

    def packet_after_pulse(current: float) -> float:
        spk = SpikingPopulation(axes, prm, dt_s=0.001, seed=4)
        dec = SpikeCountDecoder(axes, window_steps=50, half_width=10)
        spk.kick([100.0])
        for _ in range(300):
            dec.add(spk.step())
        template = np.roll(dec.counts.astype(np.float64), 90)
        for _ in range(int(round(p["spiking_inject_s"] / 0.001))):
            dec.add(spk.step(current=current * template / template.max()))
        for _ in range(300):
            dec.add(spk.step())
        return float(dec.decode()[0])

    def ring_distance(a: float, b: float) -> float:
        return abs((a - b + 180.0) % 360.0 - 180.0)

    assert ring_distance(packet_after_pulse(p["spiking_inject_current"]), 190.0) < 3.0
    assert ring_distance(packet_after_pulse(10.0), 100.0) < 3.0


# --------------------------------------------------------------- bad input
BAD = [("duration_s", 1.0), ("duration_s", float("nan")), ("model", "grid_cells"), ("trajectory", "x"),
       ("heading_bins", 0), ("landmark_radius_m", -0.1), ("inject_energy", -1.0), ("ring_exc_width", 4),
       ("sheet_cells", 3), ("spiking_dt_s", 0.01), ("anchoring", "yes"), ("nonsense", 1),
       ("spiking_inject_s", 0.0), ("spiking_inject_s", float("inf")), ("spiking_inject_current", -1.0),
       ("start_s", -1.0), ("start_s", float("nan"))]


@pytest.mark.parametrize("key, value", BAD)
def test_bad_parameters_are_typed_errors(key, value):
    with pytest.raises(CansimError):
        rt.check_params({key: value})


@pytest.mark.fuzz
@settings(max_examples=40, deadline=None)
@given(st.dictionaries(st.sampled_from(sorted(rt.DEFAULTS)),
                       st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                                 st.text(max_size=5), st.booleans()), max_size=3))
def test_check_params_accepts_or_raises_a_typed_error(params):
    try:
        p = rt.check_params(params)
    except CansimError:
        return
    assert set(p) == set(rt.DEFAULTS)


def test_simulate_refuses_what_is_not_a_trajectory():
    with pytest.raises(InvalidInputError, match="RatTrajectory"):
        rt.simulate(np.zeros((10, 2)), {}, 0)


# ------------------------------------------------------------ the quick study
@pytest.mark.slow
@needs_data
def test_quick_study_writes_its_figures_and_reanchoring_lowers_the_drift(tmp_path):
    from entry_point import run_cansim

    done = run_cansim("study", "rat", "--quick", "--out", str(tmp_path))  # the installed entry point
    assert done.returncode == 0, done.stderr[-3000:]
    for name in ("rat_trajectories_paths.png", "rat_trajectories_errors.png"):
        assert (tmp_path / name).stat().st_size > 20_000
    metrics = json.loads((tmp_path / "rat_trajectories_metrics.json").read_text())
    rows = {(r["model"], r["anchoring"]): r for r in metrics["summary"]}
    assert set(rows) == {(m, a) for m in rt.MODELS for a in (False, True)}
    assert metrics["seeds"] == [0, 1]
    # the headline, on every attractor: learnt LV -> attractor weights lower the mean drift of seeds 0-1
    # (measured: rate ring 12.5 -> 4.0 deg/min, spiking ring 12.4 -> 6.0 deg/min, sheet 0.065 -> 0.022 m/min)
    for model in rt.MODELS:
        assert rows[(model, True)]["drift_per_min"] < 0.7 * rows[(model, False)]["drift_per_min"], model
        assert rows[(model, True)]["n_views"] > 0 and rows[(model, False)]["n_views"] == 0


def test_the_errors_figure_draws_every_seed_as_median_and_range():
    """Two seeds of one model: one line at the per-sample median of the two, a band between them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(5) * 0.5 * 60.0  # s
    runs = [rt.DriftRun("rate_ring", False, t, np.zeros(5), np.zeros(5), np.array(e, float), "deg")
            for e in ([0, 1, 2, 3, 4], [0, 3, 2, 1, 8], [0, 2, 5, 2, 6])]
    fig, axes = plt.subplots(2, 1)
    rt.plot_errors(runs, axes)
    lines = axes[0].get_lines()
    assert len(lines) == 1  # one line for the three seeds, not one per seed
    np.testing.assert_array_equal(lines[0].get_xdata(), [0, 0.5, 1, 1.5, 2])  # minutes
    np.testing.assert_array_equal(lines[0].get_ydata(), [0, 2, 2, 2, 6])  # the median by hand
    band = axes[0].collections[0].get_paths()[0].vertices[:, 1]
    assert band.min() == 0 and band.max() == 8  # the range by hand
    assert "3 seeds" in lines[0].get_label()
    plt.close(fig)


@needs_data
def test_the_landmark_radius_flag_reaches_every_run_and_the_metrics(tmp_path):
    """``--landmark-radius-m``: larger discs are entered on more samples (the flag reaches the simulation), the
    metrics record the radius, and a radius outside (0, 1] m is refused before any run."""
    args = ["--duration-s", "60", "--seeds", "1", "--no-spiking"]
    assert rt.main([*args, "--out", str(tmp_path / "default")]) == 0
    assert rt.main([*args, "--landmark-radius-m", "0.2", "--out", str(tmp_path / "wide")]) == 0
    default, wide = (json.loads((tmp_path / d / "rat_trajectories_metrics.json").read_text()) for d in ("default", "wide"))
    assert default["landmark_radius_m"] == 0.05 and wide["landmark_radius_m"] == 0.2
    inside = {d["landmark_radius_m"]: [r["anchor_samples"] for r in d["runs"] if r["anchoring"]] for d in (default, wide)}
    assert all(w > n for w, n in zip(inside[0.2], inside[0.05])), inside
    for bad in ("0", "-0.1", "1.5", "nan"):
        with pytest.raises(SystemExit) as stop:
            rt.main([*args, "--landmark-radius-m", bad, "--out", str(tmp_path / "bad")])
        assert stop.value.code == 2
    assert not (tmp_path / "bad").exists()


@needs_data
def test_the_progress_bar_counts_the_runs_and_no_progress_hides_it(tmp_path, capsys):
    args = ["--duration-s", "30", "--seeds", "1", "--no-spiking"]
    assert rt.main([*args, "--out", str(tmp_path / "shown")]) == 0
    shown = capsys.readouterr().err
    assert "rat study" in shown and f"{2 * (len(rt.MODELS) - 1)}/{2 * (len(rt.MODELS) - 1)}" in shown  # models x anchoring
    assert rt.main([*args, "--no-progress", "--out", str(tmp_path / "hidden")]) == 0
    assert "rat study" not in capsys.readouterr().err
