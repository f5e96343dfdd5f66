"""Robot arm drivers behind one :class:`Arm` interface.

* :class:`URArm`: a Universal Robots UR5/UR10 over ``ur-rtde`` (no ROS):
  ``RTDEReceiveInterface`` for the TCP pose, joint state and controller
  timestamps; ``RTDEControlInterface`` for ``moveL``, ``servoL``, ``moveJ``
  and ``stopL``.
* :class:`SimArm`: a kinematic arm (instant or rate-limited motion on a
  simulated clock) for the simulator and the tests.

Safety is part of the driver, not of the caller: every public command of
:class:`Arm` first reads a fresh state, then passes the target through the
:class:`~whisker_io.hw.safety.SafetyEnvelope`, and only then calls the
implementation's private ``_move_linear``/``_servo_linear``/``_move_joints``.
A refused command raises :class:`~whisker_io.errors.SafetyViolationError`
and nothing reaches the robot. Stale or lost state raises
:class:`~whisker_io.errors.StaleStateError` /
:class:`~whisker_io.errors.ConnectionFailedError` after a best-effort stop.

Poses cross the interface as :class:`~whisker_io.pose.Pose` (position in
m + scalar-last quaternion); a 4x4 transform or a UR 6-vector is accepted too.
"""

from __future__ import annotations

import abc
import logging
import socket
import struct
import time
from dataclasses import dataclass
from typing import Any, Callable, Optional

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from whisker_io.errors import (CommandFailedError, ConnectionFailedError, HardwareError, InvalidInputError,
                               SafetyViolationError)
from whisker_io.hw.optional import require
from whisker_io.pose import Pose, PoseLike
from whisker_io.hw.safety import SafetyEnvelope

__all__ = ["ArmState", "Arm", "SimArm", "SentCommand", "URArm", "probe_rtde", "CommandFailedError",
           "RTDE_PORT", "RECEIVE_VARIABLES"]

_LOG = logging.getLogger(__name__)

#: TCP port of the RTDE interface (fixed by the UR controller and ur-rtde).
RTDE_PORT = 30004

#: RTDE output variables URArm subscribes to (a short recipe keeps it light).
RECEIVE_VARIABLES = ("timestamp", "actual_TCP_pose", "actual_q", "actual_qd")




@dataclass(frozen=True)
class ArmState:
    """One state sample of the arm.

    Attributes
    ----------
    timestamp : float
        Controller time in s (UR: seconds since controller start; SimArm:
        simulated time).
    pose : Pose
        Tool pose in the base frame.
    q : numpy.ndarray, shape (6,)
        Joint angles in rad.
    qd : numpy.ndarray, shape (6,)
        Joint speeds in rad/s.
    """

    timestamp: float
    pose: Pose
    q: np.ndarray
    qd: np.ndarray


class Arm(abc.ABC):
    """A robot arm whose every command is checked by a safety envelope.

    Subclasses implement ``_read_state``, ``_move_linear``, ``_servo_linear``,
    ``_move_joints``, ``_stop`` and ``_close``; the public methods here do
    the checking, so no implementation can skip it.

    Parameters
    ----------
    envelope : SafetyEnvelope, optional
        Limits; the safe defaults of :class:`SafetyEnvelope` if omitted.
    """

    def __init__(self, envelope: Optional[SafetyEnvelope] = None) -> None:
        self.envelope = envelope if envelope is not None else SafetyEnvelope()
        if not isinstance(self.envelope, SafetyEnvelope):
            raise InvalidInputError("envelope must be a SafetyEnvelope")
        self._servo_previous: Optional[Pose] = None
        self._closed = False

    # -------------------------------------------------------------- interface
    @abc.abstractmethod
    def _read_state(self) -> ArmState: ...

    @abc.abstractmethod
    def _move_linear(self, target: Pose, speed: float, acceleration: float) -> None: ...

    @abc.abstractmethod
    def _servo_linear(self, target: Pose, dt: float) -> None: ...

    @abc.abstractmethod
    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None: ...

    @abc.abstractmethod
    def _stop(self) -> None: ...

    def _close(self) -> None:
        """Release connections (default: nothing)."""

    # ----------------------------------------------------------------- public
    def state(self) -> ArmState:
        """Fresh arm state. Stops the arm and raises on a fault.

        Raises
        ------
        StaleStateError
            The state has not advanced for ``envelope.staleness_timeout`` s.
        ConnectionFailedError
            The link to the controller is lost.
        SafetyViolationError
            Observed joint speeds exceed the envelope.
        """
        self._check_open()
        try:
            st = self._read_state()
            self.envelope.check_joint_speeds(st.qd)
        except HardwareError:
            self.safe_stop()
            raise
        return st

    def pose(self) -> Pose:
        """Current tool pose (a fresh :meth:`state`)."""
        return self.state().pose

    def move_linear(self, target: PoseLike, speed: Optional[float] = None,
                    acceleration: Optional[float] = None) -> Pose:
        """Move the tool in a straight line to ``target`` (blocking, ``moveL``).

        Parameters
        ----------
        target : PoseLike
            Target tool pose in the base frame.
        speed : float, optional
            Tool speed in m/s; default ``envelope.max_tcp_speed``.
        acceleration : float, optional
            Tool acceleration in m/s^2; default ``envelope.max_tcp_acceleration``.

        Returns
        -------
        Pose
            The target as sent (unchanged).

        Raises
        ------
        SafetyViolationError
            The move leaves the envelope; nothing was sent.
        """
        current = self.state().pose
        speed = self.envelope.max_tcp_speed if speed is None else speed
        acceleration = self.envelope.max_tcp_acceleration if acceleration is None else acceleration
        pose = self.envelope.check_move_linear(current, target, speed, acceleration)
        self._servo_previous = None
        self._move_linear(pose, float(speed), float(acceleration))
        return pose

    def servo_linear(self, target: PoseLike, dt: float) -> Pose:
        """One step of real-time servoing toward ``target`` (``servoL``).

        The step from the previous servo target (or from the current pose on
        the first step) must stay within ``max_servo_step``,
        ``max_servo_rotation_step`` and ``max_tcp_speed``. Call it every
        ``dt`` seconds; each call also checks the state is fresh.
        """
        current = self.state().pose
        previous = self._servo_previous if self._servo_previous is not None else current
        pose = self.envelope.check_servo(previous, target, dt)
        self._servo_linear(pose, float(dt))
        self._servo_previous = pose
        return pose

    def move_joints(self, q, speed: Optional[float] = None,
                    acceleration: Optional[float] = None) -> np.ndarray:
        """Move in joint space to ``q`` (rad, shape (6,)) at ``speed`` rad/s
        (default ``envelope.max_joint_speed``, 0.1 rad/s as in Sec 2.2.1)."""
        self.state()
        speed = self.envelope.max_joint_speed if speed is None else speed
        acceleration = (self.envelope.max_joint_acceleration if acceleration is None
                        else acceleration)
        qt = self.envelope.check_move_joints(q, speed, acceleration)
        self._servo_previous = None
        self._move_joints(qt, float(speed), float(acceleration))
        return qt

    def stop(self) -> None:
        """Decelerate to a stop (always allowed)."""
        self._check_open()
        self._servo_previous = None
        self._stop()

    def guard_deflection(self, deflection) -> None:
        """Stop the arm and raise on deflection overload.

        Parameters
        ----------
        deflection : array_like
            x/y deflections in ADC counts (any shape).

        Raises
        ------
        SafetyViolationError
            Some ``|deflection|`` exceeds ``envelope.max_deflection``.
        """
        try:
            self.envelope.check_deflection(deflection)
        except SafetyViolationError:
            self.safe_stop()
            raise

    def close(self) -> None:
        """Stop and release the connection; further calls raise."""
        if self._closed:
            return
        try:
            self.safe_stop()
            self._close()
        finally:
            self._closed = True

    def __enter__(self) -> "Arm":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---------------------------------------------------------------- helpers
    def _check_open(self) -> None:
        if self._closed:
            raise ConnectionFailedError(f"{type(self).__name__} is closed; create a new one")

    def safe_stop(self) -> None:
        """Stop, logging instead of raising if the link is already gone (used after
        faults, where a failing stop must not mask the original error)."""
        if self._closed:
            return
        try:
            self._servo_previous = None
            self._stop()
        except Exception as exc:  # the link may be gone; stopping must not mask the fault
            _LOG.warning("stop after fault failed: %s", exc)


# --------------------------------------------------------------------- SimArm
@dataclass
class SentCommand:
    kind: str
    target: Any
    speed: float
    acceleration_or_dt: float


class SimArm(Arm):
    """Kinematic arm: instant, or rate-limited on a simulated clock.

    Parameters
    ----------
    initial_pose : PoseLike, optional
        Start pose; default 0.4 m in front of the base, 0.4 m up, tool down.
        It must be inside the envelope.
    envelope : SafetyEnvelope, optional
        Limits (safe defaults).
    rate_limited : bool
        False: a move completes instantly (the clock advances by
        ``control_period``). True: the move takes ``distance / speed`` seconds
        of simulated time and the intermediate poses are appended to
        :attr:`trajectory` every ``control_period``.
    control_period : float
        Simulated controller period in s (UR e-series: 0.002).

    Attributes
    ----------
    received : list
        Every command that reached the simulated robot (after the envelope),
        as ``SentCommand(kind, target, speed, acceleration_or_dt)``.
    trajectory : list of (float, Pose)
        Time-stamped poses (rate-limited mode, plus one per instant move).

    Notes
    -----
    SimArm has no joint model: ``q`` is the last ``move_joints`` target
    (zeros at start) and ``qd`` is zero. There is no IK, so a joint move does
    not change the tool pose.
    """

    def __init__(self, initial_pose: Optional[PoseLike] = None,
                 envelope: Optional[SafetyEnvelope] = None, *,
                 rate_limited: bool = False, control_period: float = 0.002) -> None:
        super().__init__(envelope)
        if not (np.isfinite(control_period) and control_period > 0):
            raise InvalidInputError("control_period must be a positive number of seconds")
        if initial_pose is None:
            initial_pose = Pose([0.4, 0.0, 0.4], [1.0, 0.0, 0.0, 0.0])
        try:
            self._pose = self.envelope.check_pose(initial_pose)
        except SafetyViolationError as exc:
            raise InvalidInputError(f"initial_pose must be inside the envelope: {exc}") from exc
        self.rate_limited = bool(rate_limited)
        self.control_period = float(control_period)
        self.time = 0.0
        self._q = np.zeros(6)
        self.received: list[SentCommand] = []
        self.trajectory: list[tuple[float, Pose]] = [(0.0, self._pose)]

    def _read_state(self) -> ArmState:
        return ArmState(self.time, self._pose, self._q.copy(), np.zeros(6))

    def _advance_to(self, target: Pose, duration: float) -> None:
        start = self._pose
        n = max(1, int(np.ceil(duration / self.control_period))) if self.rate_limited else 1
        if self.rate_limited and n > 1:
            rots = Slerp([0.0, 1.0], Rotation.concatenate([start.rotation, target.rotation]))
            for k in range(1, n):
                s = k / n
                # a + s (b - a), kept inside the box the two ends span: every simulated pose
                # satisfies each axis limit both ends satisfy (no 0.049999... under a 0.05 floor)
                a, b = start.position_m, target.position_m
                p = Pose.from_rotation(np.clip(a + s * (b - a), np.minimum(a, b), np.maximum(a, b)), rots(s))
                self.trajectory.append((self.time + k * duration / n, p))
        self.time += duration if self.rate_limited else self.control_period
        self._pose = target
        self.trajectory.append((self.time, target))

    def _move_linear(self, target: Pose, speed: float, acceleration: float) -> None:
        self.received.append(SentCommand("moveL", target, speed, acceleration))
        dist, _ = self._pose.distance_to(target)
        self._advance_to(target, max(dist / speed, self.control_period))

    def _servo_linear(self, target: Pose, dt: float) -> None:
        self.received.append(SentCommand("servoL", target, 0.0, dt))
        self._advance_to(target, dt)

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        self.received.append(SentCommand("moveJ", q.copy(), speed, acceleration))
        duration = float(np.max(np.abs(q - self._q))) / speed
        self._q = q.copy()
        self.time += duration if self.rate_limited else self.control_period

    def _stop(self) -> None:
        self.received.append(SentCommand("stop", None, 0.0, 0.0))


# ---------------------------------------------------------------------- URArm
def probe_rtde(host: str, port: int = RTDE_PORT, timeout: float = 0.5) -> None:
    """Check that an RTDE server answers, with a short socket timeout.

    Connects, sends ``RTDE_REQUEST_PROTOCOL_VERSION`` (version 2) and waits
    for the 3-byte reply header. This runs *before* ur-rtde's constructor,
    which blocks in C++ (holding the interpreter lock) for > 40 s on a host
    that accepts but never answers.

    Raises
    ------
    ConnectionFailedError
        Nothing listening (refused), no route, timeout on connect, or a server
        that accepts but does not answer the protocol request in ``timeout`` s.
    """
    request = struct.pack(">HBH", 5, ord("V"), 2)
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            sock.sendall(request)
            reply = b""
            while len(reply) < 3:
                chunk = sock.recv(3 - len(reply))
                if not chunk:
                    raise ConnectionFailedError(
                        f"RTDE server at {host}:{port} closed the connection during the probe; "
                        "is another client holding the robot, or is RTDE disabled?")
                reply += chunk
    except socket.timeout as exc:
        raise ConnectionFailedError(
            f"RTDE server at {host}:{port} did not answer within {timeout} s; check that "
            "the robot is powered on, the IP is right and RTDE is enabled") from exc
    except OSError as exc:
        raise ConnectionFailedError(
            f"cannot connect to the robot at {host}:{port} ({exc.strerror or exc}); "
            "check the IP address and the network cable") from exc
    if reply[2] != ord("V"):
        raise ConnectionFailedError(
            f"{host}:{port} answered with package type {reply[2]!r}, not RTDE; wrong host/port?")


class URArm(Arm):
    """Universal Robots arm over ur-rtde, guarded by a safety envelope.

    Parameters
    ----------
    host : str
        Controller IP address.
    envelope : SafetyEnvelope, optional
        Limits (safe defaults).
    frequency : float
        RTDE receive frequency in Hz; -1 lets ur-rtde choose (125 Hz CB3,
        500 Hz e-series).
    probe_timeout : float
        Socket timeout (s) of the :func:`probe_rtde` run before ur-rtde's
        blocking constructors.
    connect_timeout : float
        Time (s) to wait for the first streamed states after connecting.
    control : bool
        False opens the arm read-only (no ``RTDEControlInterface``); commands
        then raise :class:`CommandFailedError`.
    receive_factory, control_factory : callable, optional
        ``factory(host) -> interface`` replacing the ur-rtde constructors
        (test doubles). The probe runs only if a ur-rtde constructor is used.

    Raises
    ------
    ConnectionFailedError
        Unreachable host, a server that never answers, or no states streamed.
    MissingDependencyError
        ur-rtde is not installed (``pip install "cansim[hw]"``).

    Notes
    -----
    Staleness: ur-rtde keeps returning the last received state after the
    link drops. Every :meth:`state` compares the controller ``timestamp``
    with the previous one and raises :class:`StaleStateError` when it has not
    advanced for ``envelope.staleness_timeout`` s (<= 1 s) of wall time, or
    :class:`ConnectionFailedError` when ur-rtde reports the link down.
    ``moveL``/``moveJ`` are blocking; the controller enforces the commanded
    speed, and observed joint speeds are checked at every state read.
    """

    def __init__(self, host: str, envelope: Optional[SafetyEnvelope] = None, *,
                 frequency: float = -1.0, probe_timeout: float = 0.5,
                 connect_timeout: float = 2.0, control: bool = True,
                 receive_factory: Optional[Callable[[str], Any]] = None,
                 control_factory: Optional[Callable[[str], Any]] = None,
                 servo_lookahead: float = 0.1, servo_gain: float = 300.0,
                 stop_deceleration: float = 2.0) -> None:
        super().__init__(envelope)
        self.host = host
        self.servo_lookahead = float(servo_lookahead)
        self.servo_gain = float(servo_gain)
        self.stop_deceleration = float(stop_deceleration)
        if receive_factory is None or (control and control_factory is None):
            probe_rtde(host, RTDE_PORT, probe_timeout)
        if receive_factory is None:
            rtde_receive = require("rtde_receive", "URArm")

            def receive_factory(h: str) -> Any:
                return rtde_receive.RTDEReceiveInterface(h, frequency, list(RECEIVE_VARIABLES))
        if control and control_factory is None:
            rtde_control = require("rtde_control", "URArm")

            def control_factory(h: str) -> Any:
                return rtde_control.RTDEControlInterface(h, frequency)
        try:
            self._receive = receive_factory(host)
        except RuntimeError as exc:
            raise ConnectionFailedError(f"RTDE receive interface to {host} failed: {exc}") from exc
        self._last_timestamp: Optional[float] = None
        self._last_change = time.monotonic()
        self._wait_for_stream(connect_timeout)
        self._control = None
        if control:
            try:
                self._control = control_factory(host)
            except RuntimeError as exc:
                self._receive.disconnect()
                raise ConnectionFailedError(f"RTDE control interface to {host} failed: {exc}") from exc

    def _wait_for_stream(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        seen = set()
        while time.monotonic() < deadline:
            before = len(seen)
            if self._receive.isConnected():
                seen.add(float(self._receive.getTimestamp()))
                if len(seen) >= 2:  # two distinct controller times: the stream is live
                    self._last_timestamp = max(seen)
                    self._last_change = time.monotonic()
                    return
            if len(seen) == before:
                # polling ur-rtde's C++ state buffer: it offers no event to wait on
                time.sleep(0.0005)
        self._receive.disconnect()
        raise ConnectionFailedError(
            f"connected to {self.host} but no robot state was streamed within {timeout} s")

    def _read_state(self) -> ArmState:
        if not self._receive.isConnected():
            raise ConnectionFailedError(
                f"RTDE link to {self.host} is down; check the cable, then create a new URArm")
        ts = float(self._receive.getTimestamp())
        now = time.monotonic()
        if ts != self._last_timestamp:
            self._last_timestamp = ts
            self._last_change = now
        self.envelope.check_fresh(now - self._last_change)
        try:
            pose = Pose.from_ur(self._receive.getActualTCPPose())
            q = np.asarray(self._receive.getActualQ(), dtype=float)
            qd = np.asarray(self._receive.getActualQd(), dtype=float)
        except InvalidInputError as exc:
            raise ConnectionFailedError(f"malformed state from {self.host}: {exc}") from exc
        if q.shape != (6,) or qd.shape != (6,):
            raise ConnectionFailedError(f"malformed joint state from {self.host}")
        return ArmState(ts, pose, q, qd)

    def _require_control(self) -> Any:
        if self._control is None:
            raise CommandFailedError("URArm was opened read-only (control=False)")
        return self._control

    @staticmethod
    def _ok(result: Any, what: str) -> None:
        if result is False:
            raise CommandFailedError(f"controller refused {what}; check the pendant for a "
                                     "protective stop and that remote control is enabled")

    def _move_linear(self, target: Pose, speed: float, acceleration: float) -> None:
        self._ok(self._require_control().moveL(target.as_ur(), speed, acceleration, False),
                 "moveL")

    def _servo_linear(self, target: Pose, dt: float) -> None:
        self._ok(self._require_control().servoL(target.as_ur(), 0.0, 0.0, dt,
                                                self.servo_lookahead, self.servo_gain), "servoL")

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        self._ok(self._require_control().moveJ([float(v) for v in q], speed, acceleration,
                                               False), "moveJ")

    def _stop(self) -> None:
        if self._control is None:
            return
        self._control.servoStop(self.stop_deceleration * 5)
        self._control.stopL(self.stop_deceleration, False)

    def _close(self) -> None:
        for iface in (self._control, self._receive):
            if iface is None:
                continue
            try:
                iface.disconnect()
            except RuntimeError as exc:
                _LOG.warning("disconnect failed: %s", exc)
