"""examples/hardware_exploration.py end to end: the fake RTDE server (ur-rtde's receive interface over a
socket), an in-process fake control interface and the fake USB backend; exit codes; replay = live."""

from __future__ import annotations

import csv
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
import hardware_exploration as hx  # noqa: E402

needs_hw = pytest.mark.skipif(importlib.util.find_spec("rtde_receive") is None or importlib.util.find_spec("usb") is None,
                              reason='needs the hw extra (pip install -e ".[hw]")')


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    """A saved object model (a short simulated Box map) and a quickly trained svr10 model."""
    from cansim.explore.explorer import build_object_model
    from whisker_io.radial.features import RadialDataset
    from whisker_io.radial.models import SearchParams, train_models
    from whisker_io.radial.persistence import save_model
    from whisker_io.sim.objects import make_object
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    d = tmp_path_factory.mktemp("hx")
    mesh = make_object("box")
    chain, rng = WhiskChain(mesh, contact_model="tip"), np.random.default_rng(0)
    k = build_object_model("box", object_trajectory(mesh, "A", n_loops=1)[:20], lambda p: chain.features(p, rng),
                           hx.exact_odometry(), placement=None)
    k.model.save(d / "box.npz")
    k.save(d / "box_known.npz")  # the model with its mapping log (the surface matcher's input)
    n = 200
    wl = rng.choice([0.065, 0.087, 0.137], n)
    s, av = rng.uniform(0.2, 1.0, n), rng.uniform(0.5, 4.0, n)
    cp, ca = s / av, 2000.0 * (1.2 - s)
    X = np.column_stack([cp, ca, ca / cp, ca / cp / cp, av, rng.normal(0, 1, n), wl])
    model = train_models(RadialDataset(X, wl * s, name="known"), ["svr10"], SearchParams().quick())["svr10"]
    save_model(model, d / "svr10.skops")
    return d


def test_usage_errors_exit_2(assets, capsys):
    with pytest.raises(SystemExit) as e:
        hx.main(["--no-such-option"])
    assert e.value.code == 2
    assert hx.main(["--robot-ip", "127.0.0.3", "--radial-model", str(assets / "svr10.skops")]) == 2  # no --map
    assert hx.main(["--robot-ip", "127.0.0.3", "--radial-model", str(assets / "none.skops"), "--map", f"box={assets / 'box.npz'}"]) == 2
    assert hx.main(["--robot-ip", "127.0.0.3", "--radial-model", str(assets / "svr10.skops"), "--map", "box"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "invalid --map" in err
    # a map given twice, an empty map, an object library: usage errors saying so (they were exit 1 or "corrupt")
    from cansim.models.whisker_ratslam import WhiskerRatSLAM

    WhiskerRatSLAM(backend="numpy").save(assets / "empty.npz")
    base = ["--robot-ip", "127.0.0.3", "--radial-model", str(assets / "svr10.skops")]
    for maps, says in (([f"box={assets / 'box.npz'}", f"box={assets / 'box_known.npz'}"], "box is given twice"),
                       ([f"nothing={assets / 'empty.npz'}"], "the map holds no experience"),
                       ([f"box={assets / 'svr10.skops'}"], "this file is a scikit-learn model")):
        assert hx.main(base + [a for m in maps for a in ("--map", m)]) == hx.EXIT_USAGE
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err and "Traceback" not in err


def test_the_decision_is_the_first_ic_over_the_threshold_or_nothing():
    from types import SimpleNamespace

    ic = [[0.0, 0.0], [120.0, 310.0], [320.0, 400.0]]  # b reaches 300 first (whisk 1), a later
    assert hx.decision(["a", "b"], SimpleNamespace(ic=ic), 300.0) == "decided: b (IC >= 300)"
    assert hx.decision(["a", "b"], SimpleNamespace(ic=[[0.0, 0.0]] * 3), 300.0) == "decided: nothing (no IC reached 300)"
    assert hx.decision(["a", "b"], SimpleNamespace(ic=[]), 300.0) == "decided: nothing (no IC reached 300)"


@needs_hw
def test_no_robot_reachable_exits_3(assets, capsys):
    # 127.0.0.3: loopback where nothing listens (the fake server binds 127.0.0.1 only)
    rc = hx.main(["--robot-ip", "127.0.0.3", "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}"])
    err = capsys.readouterr().err.strip()
    assert rc == hx.EXIT_NO_ROBOT and "no robot reachable at 127.0.0.3" in err and err.count("\n") == 0


@needs_hw
def test_end_to_end_on_the_fakes_and_replay(assets, tmp_path, capsys):
    from whisker_io.hw.safety import SafetyEnvelope
    from whisker_io.hw.usb_array import FrameLayout
    from whisker_io.pose import Pose
    from whisker_io.testing.fake_rtde_server import FakeControlInterface, FakeServerError, fake_rtde_server
    from whisker_io.testing.fake_usb_backend import FakeUSBBackend

    layout = FrameLayout()
    T, M = 2000, 18

    def whisk(k):
        s = np.zeros((T, M, 3))
        s[:, :, 0] = np.linspace(-0.8727, 0.8727, T)[:, None]
        return s

    control = FakeControlInterface()
    backend = FakeUSBBackend(layout, source=whisk)
    out = tmp_path / "session"
    args = ["--robot-ip", "127.0.0.1", "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}",
            "--iterations", "6", "--object-centre", "0.4", "0.0", "0.3", "--object-radius", "0.1", "--out", str(out)]
    try:
        with fake_rtde_server("stream"):
            rc = hx.main(args, control_factory=lambda h: control, usb_backend=backend)
    except FakeServerError as exc:
        pytest.skip(f"cannot run the fake RTDE server on port 30004: {exc}")
    assert rc == hx.EXIT_OK
    printed = capsys.readouterr().out.splitlines()
    assert printed[-1] == "decided: nothing (no IC reached 300)"  # not the first object of a row of zeros
    # RCP retract-at-max was set on the array before whisking
    assert len(backend.commands) >= 3
    from scipy.spatial.transform import Rotation

    env = SafetyEnvelope(max_tool_tilt=math.pi / 2 + 1e-6)  # the driver's limit; 1e-6 rad for the rotvec round trip
    motions = control.motions()
    assert motions, "the explorer moved the arm"
    for name, a in motions:
        assert name == "moveL"
        target = np.asarray(a[0], dtype=float)
        env.check_pose(Pose.from_rotation(target[:3], Rotation.from_rotvec(target[3:])))
    with open(out / "exploration.csv", newline="") as f:
        live = list(csv.DictReader(f))
    assert len(live) == 6
    assert hx.main(["--replay", str(out), "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}"]) == 0
    with open(out / "exploration_replay.csv", newline="") as f:
        rep = list(csv.DictReader(f))
    assert [r["ic_box"] for r in rep] == [r["ic_box"] for r in live]
    # the surface matcher replays the session from a map saved with its mapping log; a bare model is refused (usage)
    surface = ["--replay", str(out), "--radial-model", str(assets / "svr10.skops"), "--matcher", "surface"]
    assert hx.main(surface + ["--map", f"box={assets / 'box_known.npz'}"]) == 0
    with open(out / "exploration_replay.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) == len(live)
    assert hx.main(surface + ["--map", f"box={assets / 'box.npz'}"]) == hx.EXIT_USAGE
    # a replay honours --iterations and --out (it replayed everything into the session folder), and a missing
    # session is a usage error
    elsewhere = tmp_path / "replays"
    assert hx.main(["--replay", str(out), "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}",
                    "--iterations", "3", "--out", str(elsewhere)]) == 0
    with open(elsewhere / "exploration_replay.csv", newline="") as f:
        assert [r["ic_box"] for r in csv.DictReader(f)] == [r["ic_box"] for r in live][:3]
    assert hx.main(["--replay", str(tmp_path / "no_session"), "--radial-model", str(assets / "svr10.skops"),
                    "--map", f"box={assets / 'box.npz'}"]) == hx.EXIT_USAGE


@needs_hw
def test_ctrl_c_stops_with_one_line_and_keeps_the_whisks(assets, tmp_path, capsys):
    from whisker_io.hw.usb_array import FrameLayout
    from whisker_io.testing.fake_rtde_server import FakeControlInterface, FakeServerError, fake_rtde_server
    from whisker_io.testing.fake_usb_backend import FakeUSBBackend

    T, M = 2000, 18

    def whisk(k):
        if k == 3:
            raise KeyboardInterrupt  # the user's Ctrl-C during the fourth whisk
        s = np.zeros((T, M, 3))
        s[:, :, 0] = np.linspace(-0.8727, 0.8727, T)[:, None]
        return s

    out = tmp_path / "session"
    args = ["--robot-ip", "127.0.0.1", "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}",
            "--iterations", "6", "--object-centre", "0.4", "0.0", "0.3", "--object-radius", "0.1", "--out", str(out)]
    try:
        with fake_rtde_server("stream"):
            rc = hx.main(args, control_factory=lambda h: FakeControlInterface(),
                         usb_backend=FakeUSBBackend(FrameLayout(), source=whisk))
    except FakeServerError as exc:
        pytest.skip(f"cannot run the fake RTDE server on port 30004: {exc}")
    err = capsys.readouterr().err
    assert rc == hx.EXIT_INTERRUPTED and "Traceback" not in err
    assert err.strip() == f"hardware_exploration: interrupted after 3 whisks, kept in {out}; their trace: --replay {out}"
    from whisker_io.records.recording import replay

    assert len(list(replay(out))) == 3


def test_an_out_folder_that_is_no_session_is_refused_before_the_arm_moves(assets, tmp_path, capsys):
    (tmp_path / "whisk_000000_A1.csv").write_text("angle_rad,x_deflection_counts,y_deflection_counts,spare\n0,0,0,0\n")
    calls = []
    rc = hx.main(["--robot-ip", "127.0.0.1", "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}",
                  "--out", str(tmp_path)], control_factory=lambda h: calls.append(h))
    assert rc == hx.EXIT_USAGE and not calls  # no connection was made
    assert "has no pose_log.csv" in capsys.readouterr().err
    assert (tmp_path / "whisk_000000_A1.csv").exists()


def test_ctrl_c_outside_the_live_run_is_one_line_and_130(assets, capsys, monkeypatch):
    """Loading the maps (or a replay, or writing the trace) interrupted: one line, status 130, no traceback."""
    def interrupted(specs):
        raise KeyboardInterrupt

    monkeypatch.setattr(hx, "load_known", interrupted)
    rc = hx.main(["--replay", str(assets), "--radial-model", str(assets / "svr10.skops"), "--map", f"box={assets / 'box.npz'}"])
    err = capsys.readouterr().err
    assert rc == hx.EXIT_INTERRUPTED and err.strip() == "hardware_exploration: interrupted"
