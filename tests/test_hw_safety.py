"""Safety envelope: every unsafe command refused, every safe one passed unchanged.

The oracle below re-derives each limit by hand (Rodrigues' formula for the
tool axis, Euclidean step lengths, plain comparisons) instead of calling the
envelope, and the commands go through the *drivers* (SimArm and URArm with an
injected fake controller), so the test also proves the check sits inside the
driver and that nothing violating reaches the robot.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from whisker_io.errors import ConfigError, SafetyViolationError, StaleStateError
from whisker_io.hw.arm import SimArm, URArm
from whisker_io.testing.fake_rtde_server import FakeControlInterface, FakeReceiveInterface
from whisker_io.pose import Pose
from whisker_io.hw.safety import SafetyEnvelope

ENV = SafetyEnvelope()
LO = np.array(ENV.workspace_min)
HI = np.array(ENV.workspace_max)
BORDER = 1e-9  # commands this close to a limit may go either way (float rounding)
SPECIALS = [math.nan, math.inf, -math.inf, 1e300, -1e300]


# ----------------------------------------------------------------- oracle
def tool_axis_from_rotvec(r):
    """z-axis of the rotation with rotation vector r (Rodrigues), by hand."""
    r = np.asarray(r, dtype=float)
    theta = math.hypot(*r)
    if theta > 2 * math.pi:
        return np.array([0.0, 0.0, 1.0])  # refused anyway by the |r| margin
    v = np.array([0.0, 0.0, 1.0])
    if theta < 1e-300:
        return v
    k = r / theta
    return v * math.cos(theta) + np.cross(k, v) * math.sin(theta) + k * (k @ v) * (1 - math.cos(theta))


def verdict(conditions):
    """conditions: list of (margin) where margin >= 0 is inside the limit.
    Returns 'safe', 'unsafe' or 'border'."""
    if any(m is None for m in conditions):
        return "unsafe"  # non-finite input
    worst = min(conditions)
    if abs(worst) <= BORDER:
        return "border"
    return "safe" if worst > 0 else "unsafe"


def pose_margins(vec):
    v = np.asarray(vec, dtype=float)
    if not np.all(np.isfinite(v)):
        return [None]
    p = v[:3]
    margins = list(p - LO) + list(HI - p)
    margins.append(2 * math.pi - math.hypot(*v[3:]))  # |r| <= 2 pi: meaningful rotation vector
    tilt = math.acos(max(-1.0, min(1.0, -tool_axis_from_rotvec(v[3:])[2])))
    margins.append(ENV.max_tool_tilt - tilt)
    return margins


def range_margin(x, limit):
    if not math.isfinite(x):
        return None
    return min(x, limit - x)


def oracle(cmd, start_vec):
    kind = cmd[0]
    if kind == "moveL":
        _, vec, speed, acc = cmd
        return verdict(pose_margins(vec) + [range_margin(speed, ENV.max_tcp_speed),
                                            range_margin(acc, ENV.max_tcp_acceleration)])
    if kind == "servoL":
        _, vec, dt = cmd
        m = pose_margins(vec)
        if None in m or min(m) < -BORDER or not math.isfinite(dt):
            return "unsafe"
        step = math.hypot(*(a - b for a, b in zip(vec[:3], start_vec[:3])))
        # relative rotation angle between the two rotation vectors, by quaternions
        q0 = _quat(start_vec[3:])
        q1 = _quat(vec[3:])
        rot = 2 * math.acos(min(1.0, abs(float(q0 @ q1))))
        m += [dt - ENV.min_servo_period, ENV.max_servo_period - dt,
              ENV.max_servo_step - step, ENV.max_servo_rotation_step - rot]
        if dt > 0:
            m.append(ENV.max_tcp_speed - step / dt)
        return verdict(m)
    _, q, speed, acc = cmd
    q = np.asarray(q, dtype=float)
    if not np.all(np.isfinite(q)):
        return "unsafe"
    return verdict(list(2 * math.pi - np.abs(q)) + [range_margin(speed, ENV.max_joint_speed),
                                                     range_margin(acc, ENV.max_joint_acceleration)])


def _quat(r):
    r = np.asarray(r, dtype=float)
    theta = math.hypot(*r)
    if theta < 1e-300:
        return np.array([0.0, 0.0, 0.0, 1.0])
    return np.concatenate([r / theta * math.sin(theta / 2), [math.cos(theta / 2)]])


# ------------------------------------------------------------- strategies
# Hypothesis' per-draw cost dominates at 10,000 examples, so each command is
# drawn flat (a kind, 8 uniform numbers, one selector) and mapped to values.
start_pose = st.tuples(st.floats(-0.45, 0.45), st.floats(-0.45, 0.45), st.floats(0.1, 0.65),
                       st.floats(-math.pi, math.pi))


def ur_vector(pos, rv):
    return [float(v) for v in list(pos) + list(rv)]


def build_command(kind, u, sel):
    """Map uniform numbers u (8 in [-1, 1]) and a selector to one command.

    Ranges straddle every limit (out-of-box positions, rotation vectors longer
    than 2 pi, over-speed, negative/zero speeds and periods, huge servo steps);
    selectors >= 48 replace one number by NaN, +-inf or +-1e300."""
    if kind == "moveL":
        nums = [0.85 * u[0] + 0.05, 0.8 * u[1], 0.55 * u[2] + 0.35, 4 * u[3], 4 * u[4], 4 * u[5],
                0.125 * u[6] + 0.075, 0.6 * u[7] + 0.4]
    elif kind == "servoL":
        step = 1.0 if sel % 4 == 0 else 0.002      # huge servo steps a quarter of the time
        turn = 1.0 if sel % 8 == 1 else 0.02
        nums = [step * u[0], step * u[1], step * u[2], turn * u[3], turn * u[4], turn * u[5],
                0.105 * u[6] + 0.095]
    else:
        nums = [7 * v for v in u[:6]] + [0.175 * u[6] + 0.125, 0.6 * u[7] + 0.4]
    if sel >= 48:
        nums[(sel - 48) % len(nums)] = SPECIALS[(sel - 48) % len(SPECIALS)]
    if kind == "moveL":
        return ("moveL", ur_vector(nums[:3], nums[3:6]), nums[6], nums[7])
    if kind == "servoL":
        return ("servoL", tuple(nums[:3]), tuple(nums[3:6]), nums[6])
    return ("moveJ", nums[:6], nums[6], nums[7])


command = st.builds(build_command, st.sampled_from(["moveL", "servoL", "moveJ"]),
                    st.tuples(*[st.floats(-1.0, 1.0)] * 8), st.integers(0, 63))


# ------------------------------------------------------- drivers
def make_arm(kind, start_vec):
    if kind == "sim":
        return SimArm(start_vec)
    ctl = FakeControlInterface()
    arm = URArm("127.0.0.1", receive_factory=lambda h: FakeReceiveInterface(start_vec),
                control_factory=lambda h: ctl)
    arm.fake_control = ctl
    return arm


def delivered(arm):
    if isinstance(arm, SimArm):
        out = []
        for c in arm.received:
            if c.kind == "moveL":
                out.append(("moveL", c.target.as_ur(), c.speed, c.acceleration_or_dt))
            elif c.kind == "servoL":
                out.append(("servoL", c.target.as_ur(), c.acceleration_or_dt))
            elif c.kind == "moveJ":
                out.append(("moveJ", c.target.tolist(), c.speed, c.acceleration_or_dt))
        return out
    out = []
    for name, args in arm.fake_control.motions():
        if name == "servoL":  # (pose, speed, acceleration, dt, lookahead, gain)
            out.append(("servoL", list(args[0]), args[3]))
        else:  # (target, speed, acceleration, asynchronous)
            out.append((name, list(args[0]), args[1], args[2]))
    return out


def run_command(arm, cmd, start_vec):
    """Send cmd through the driver; return (accepted, the command as built)."""
    kind = cmd[0]
    if kind == "servoL":
        _, dpos, drot, dt = cmd
        pos = [a + b for a, b in zip(start_vec[:3], dpos)]
        if np.all(np.isfinite(drot)) and math.hypot(*drot) <= math.pi:
            from scipy.spatial.transform import Rotation
            rv = (Rotation.from_rotvec(start_vec[3:]) * Rotation.from_rotvec(drot)).as_rotvec()
        else:
            rv = [a + b for a, b in zip(start_vec[3:], drot)]  # garbage: refused anyway
        built = ("servoL", ur_vector(pos, rv), dt)
        call = lambda: arm.servo_linear(built[1], dt)  # noqa: E731
    elif kind == "moveL":
        built = cmd
        call = lambda: arm.move_linear(cmd[1], cmd[2], cmd[3])  # noqa: E731
    else:
        built = cmd
        call = lambda: arm.move_joints(cmd[1], cmd[2], cmd[3])  # noqa: E731
    try:
        call()
    except SafetyViolationError:
        return False, built
    return True, built


def check_commands(kind, start, cmd):
    x, y, z, yaw = start
    start_vec = ur_vector((x, y, z), (math.pi * math.cos(yaw / 2), math.pi * math.sin(yaw / 2), 0.0))
    arm = make_arm(kind, start_vec)
    start_vec = arm.pose().as_ur()
    accepted, built = run_command(arm, cmd, start_vec)
    expect = oracle(built, start_vec)
    sent = delivered(arm)
    if expect != "border":
        assert accepted == (expect == "safe"), (built, expect)
    if accepted:
        assert len(sent) == 1
        # passes unchanged: the robot got exactly the converted command
        got = sent[0]
        assert got[0] == built[0]
        if built[0] == "moveJ":
            assert got[1] == [float(v) for v in built[1]] and got[2:] == (built[2], built[3])
        else:
            assert np.array_equal(got[1], Pose.from_ur(built[1]).as_ur())
            assert np.allclose(got[1][:3], built[1][:3], rtol=0, atol=0)
            assert got[2:] == tuple(built[2:])
    else:
        assert sent == []
    for got in sent:  # nothing violating reaches the robot (with float slack)
        assert oracle(got, start_vec) in ("safe", "border"), got


@pytest.mark.slow
@pytest.mark.parametrize("kind,examples", [("sim", 5000), ("ur", 5000)])
def test_random_commands_refused_or_passed_unchanged(kind, examples):
    """10,000 random commands in all (5,000 per driver)."""

    @settings(max_examples=examples, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(start=start_pose, cmd=command)
    def run(start, cmd):
        check_commands(kind, start, cmd)

    run()


# -------------------------------------------------------- hand-computed
def down(x, y, z):
    return Pose([x, y, z], [1.0, 0.0, 0.0, 0.0])  # 180 deg about x: tool z-axis = -z


def test_box_boundary_inclusive_and_just_outside_refused():
    assert ENV.check_pose(down(0.5, -0.5, 0.7)) == down(0.5, -0.5, 0.7)
    for p in [(0.5001, 0, 0.4), (0, -0.5001, 0.4), (0, 0, 0.0499), (0, 0, 0.7001)]:
        with pytest.raises(SafetyViolationError, match="outside the workspace box"):
            ENV.check_pose(down(*p))


def test_tilt_limit_hand_computed():
    # rotate the down-pointing tool by 80 deg / 100 deg about the base x-axis
    from scipy.spatial.transform import Rotation
    base = Rotation.from_quat([1.0, 0.0, 0.0, 0.0])
    ok = Pose.from_rotation([0, 0, 0.4], Rotation.from_euler("x", 80, degrees=True) * base)
    bad = Pose.from_rotation([0, 0, 0.4], Rotation.from_euler("x", 100, degrees=True) * base)
    ENV.check_pose(ok)
    with pytest.raises(SafetyViolationError, match="tilt 100.0 deg"):
        ENV.check_pose(bad)


def test_servo_speed_hand_computed():
    a = down(0.0, 0.0, 0.4)
    # 0.5 mm in 8 ms = 0.0625 m/s <= 0.1: accepted; 1 mm in 8 ms = 0.125 m/s: refused
    assert ENV.check_servo(a, down(0.0005, 0.0, 0.4), 0.008) == down(0.0005, 0.0, 0.4)
    with pytest.raises(SafetyViolationError, match="0.125 m/s"):
        ENV.check_servo(a, down(0.001, 0.0, 0.4), 0.008)
    with pytest.raises(SafetyViolationError, match="servo step 3.00 mm"):
        ENV.check_servo(a, down(0.003, 0.0, 0.4), 0.05)


def test_move_linear_rejects_path_tilting_beyond_limit():
    from scipy.spatial.transform import Rotation, Slerp
    base = Rotation.from_quat([1.0, 0.0, 0.0, 0.0])  # tool pointing down
    env = SafetyEnvelope(max_tool_tilt=math.radians(30))

    def tilt_deg(r):  # angle of the tool z-axis from straight down
        return np.degrees(np.arccos(np.clip(-r.apply([0.0, 0.0, 1.0])[..., 2], -1, 1)))

    start = Pose.from_rotation([0, 0, 0.4], Rotation.from_euler("x", 25, degrees=True) * base)
    # -25 deg is within 30, and the slerp from +25 passes through 0: accepted
    end = Pose.from_rotation([0, 0, 0.4], Rotation.from_euler("x", -25, degrees=True) * base)
    env.check_move_linear(start, end, 0.05, 0.1)
    # a rotation of ~180 deg about the tool axis keeps the tilt: accepted
    spun = Pose.from_rotation([0, 0, 0.4], start.rotation * Rotation.from_euler("z", 179, degrees=True))
    env.check_move_linear(start, spun, 0.05, 0.1)
    # tilted 25 deg about y and spun half a turn: both ends are 25 deg from down,
    # but the slerp between them swings the tool axis out past 30 deg: refused
    far = Pose.from_rotation([0, 0, 0.4], Rotation.from_euler("y", 25, degrees=True) * base
                             * Rotation.from_euler("z", 180, degrees=True))
    assert tilt_deg(start.rotation) == pytest.approx(25) and tilt_deg(far.rotation) == pytest.approx(25)
    mid = Slerp([0, 1], Rotation.concatenate([start.rotation, far.rotation]))([0.5])
    assert tilt_deg(mid)[0] > 30
    with pytest.raises(SafetyViolationError, match="orientation path tilts"):
        env.check_move_linear(start, far, 0.05, 0.1)
    arm = SimArm(start, envelope=env)
    with pytest.raises(SafetyViolationError):
        arm.move_linear(far, 0.05, 0.1)
    assert arm.received == []  # nothing was sent


def test_joint_speed_default_is_thesis_value_and_enforced():
    assert ENV.max_joint_speed == 0.1  # Sec 2.2.1 of the thesis
    arm = SimArm()
    arm.move_joints([0.1] * 6, 0.1, 0.5)
    with pytest.raises(SafetyViolationError, match="joint speed"):
        arm.move_joints([0.2] * 6, 0.1001, 0.5)
    assert [c.kind for c in arm.received] == ["moveJ"]
    with pytest.raises(SafetyViolationError, match="exceed"):
        ENV.check_joint_speeds([0.0, 0.2, 0, 0, 0, 0])


@pytest.mark.parametrize("kwargs", [
    {"max_tcp_speed": math.inf}, {"max_tcp_speed": math.nan}, {"max_tcp_speed": 0.0},
    {"max_joint_speed": 5.0}, {"staleness_timeout": 2.0}, {"max_deflection": -1.0},
    {"overload_samples": 2.5}, {"overload_samples": 0},
    {"workspace_min": (0.0, 0.0, 0.5), "workspace_max": (1.0, 1.0, 0.4)},
    {"tool_reference_axis": (0.0, 0.0, 0.0)}, {"joint_speed_tolerance": 0.5},
    # a scalar limit given as a sequence must not skip its checks (issue 17)
    {"max_tool_tilt": (0.5, 0.5, 0.7)}, {"max_deflection": (1e9, 1e9, 1e9)},
    {"max_tcp_speed": [0.05]}, {"overload_samples": (200,)}, {"max_servo_step": "0.001"},
    {"max_joint_speed": True}, {"workspace_min": 0.1}, {"workspace_max": (0.5, 0.5)},
    {"tool_reference_axis": (0.0, math.nan, -1.0)},
])
def test_envelope_cannot_be_disabled_or_widened_past_ceilings(kwargs):
    with pytest.raises(ConfigError):
        SafetyEnvelope(**kwargs)


def test_deflection_overload_stops_arm():
    arm = SimArm()
    trace = np.zeros((3, 2000))
    trace[1, 500:699] = -2001.0  # 199 samples pinned: still allowed
    trace[2, 100:1000:2] = 2047.0  # saturated often, never for long
    arm.guard_deflection(trace)
    assert arm.received == []
    trace[0, 1000:1200] = 2000.0  # 200 consecutive samples at the limit
    with pytest.raises(SafetyViolationError, match="overload: 200 consecutive"):
        arm.guard_deflection(trace)
    assert [c.kind for c in arm.received] == ["stop"]
    with pytest.raises(SafetyViolationError, match="NaN"):
        arm.guard_deflection([np.nan])


def test_staleness_limit():
    ENV.check_fresh(0.25)
    with pytest.raises(StaleStateError, match="0.300 s old"):
        ENV.check_fresh(0.3)
    with pytest.raises(StaleStateError):
        ENV.check_fresh(math.nan)


# ----------------------------------------------------------------- the envelope in a file
_LIMITS = st.fixed_dictionaries({}, optional={
    "max_tool_tilt": st.floats(0.01, math.pi), "max_tcp_speed": st.floats(0.001, 0.5),
    "max_servo_step": st.floats(1e-4, 0.02), "staleness_timeout": st.floats(0.01, 1.0),
    "overload_samples": st.integers(1, 2000),
    "workspace_min": st.tuples(*[st.floats(-1.0, -0.01)] * 3), "workspace_max": st.tuples(*[st.floats(0.06, 1.0)] * 3),  # above the default minimum (z 0.05)
    "tool_reference_axis": st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda a: math.hypot(*a) > 0.1),
})


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(limits=_LIMITS)
def test_an_envelope_saved_loads_back_equal_and_a_hand_written_file_keeps_the_defaults(tmp_path, limits):
    import json

    env = SafetyEnvelope(**limits)
    env.save(tmp_path / "env.json")
    assert SafetyEnvelope.load(tmp_path / "env.json") == env
    (tmp_path / "hand.json").write_text(json.dumps({k: list(v) if isinstance(v, tuple) else v for k, v in limits.items()}))
    hand = SafetyEnvelope.load(tmp_path / "hand.json")
    for name in SafetyEnvelope.__dataclass_fields__:  # what the file names, as given; the rest the defaults
        want = limits.get(name, getattr(ENV, name))
        assert getattr(hand, name) == (tuple(float(v) for v in want) if isinstance(want, tuple) else want), name


@pytest.mark.parametrize("text, error, says", [
    ("", "CorruptFileError", "not a JSON file"),
    ("[0.1, 0.2]", "CorruptFileError", "a JSON object of safety limits"),
    ('{"max_tcp_speed": 0.6}', "ConfigError", "max_tcp_speed must be"),  # above its hard ceiling
    ('{"max_tcp_speed": NaN}', "ConfigError", "max_tcp_speed must be finite"),
    ('{"workspace_min": [0, 0, 0], "workspace_max": [1, 1, 0]}', "ConfigError", "workspace_min must be < workspace_max"),
    ('{"max_tcp_sped": 0.1}', "UnknownFieldError", "did you mean 'max_tcp_speed'"),
    ('{"max_tool_tilt": null}', "ConfigError", "max_tool_tilt: null is no limit; give a number or leave the field out"),
])
def test_a_bad_envelope_file_is_refused_naming_the_file(tmp_path, text, error, says):
    import whisker_io.errors as errors

    path = tmp_path / "cell.json"
    path.write_text(text)
    with pytest.raises(getattr(errors, error)) as exc:
        SafetyEnvelope.load(path)
    assert says in str(exc.value) and str(path) in str(exc.value)



@settings(max_examples=40, deadline=None)
@given(limits=_LIMITS)
def test_from_limits_is_the_constructor_with_the_files_name_on_its_errors(limits):
    """from_limits(mapping) equals SafetyEnvelope(**mapping); a refused mapping's message begins with its source."""
    assert SafetyEnvelope.from_limits(dict(limits)) == SafetyEnvelope(**limits)
    with pytest.raises(ConfigError, match=r"^cell\.json: max_tool_tilt must be"):
        SafetyEnvelope.from_limits({**limits, "max_tool_tilt": 9.0}, source="cell.json")


def test_read_limits_gives_the_files_mapping_unchecked(tmp_path):
    from whisker_io.hw.safety import read_limits

    (tmp_path / "c.json").write_text('{"max_tool_tilt": 9.0, "nonsense": 1}')
    assert read_limits(tmp_path / "c.json") == {"max_tool_tilt": 9.0, "nonsense": 1}
