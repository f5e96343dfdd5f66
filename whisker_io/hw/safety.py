"""Safety envelope checked *inside* every arm driver before a command is sent.

The :class:`SafetyEnvelope` is a frozen configuration with safe defaults and
pure checking methods. Every :class:`~whisker_io.hw.arm.Arm` implementation
runs each command through it before anything reaches the robot, so a caller
cannot bypass it: there is no flag that disables the checks, limits must be
finite and positive, and each limit has a hard ceiling a configuration cannot
exceed (:data:`HARD_CEILINGS`).

A refused command raises :class:`~whisker_io.errors.SafetyViolationError`
(message says which limit and by how much) and leaves the driver unchanged.
A command that passes is returned **unchanged** (same :class:`Pose` values)
so what reaches the robot is exactly what the caller asked for.

Defaults follow the thesis' UR5 set-up (Sec 2.2.1 of the thesis: "low joint
speeds for precautionary reasons (0.1 rad/s for all joints)", UR5 reach
0.85 m): a workspace box well inside the reach, in front of and above the
base, the tool pointing down within 90 degrees, 0.1 m/s TCP speed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from collections.abc import Mapping
from typing import Any, Optional

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from whisker_io.errors import ConfigError, CorruptFileError, InvalidInputError, SafetyViolationError, StaleStateError
from whisker_io.pose import Pose, PoseLike, as_pose
from whisker_io.validation import ConfigDataclass, checked, finite_scalar, finite_vector, validate_fields, whole_number

__all__ = ["SafetyEnvelope", "HARD_CEILINGS", "read_limits"]

#: Ceilings no configuration may exceed (unit in the name of the field).
HARD_CEILINGS = {
    "max_tcp_speed": 0.5,               # m/s
    "max_tcp_acceleration": 2.0,        # m/s^2
    "max_joint_speed": 1.0,             # rad/s
    "max_joint_acceleration": 2.0,      # rad/s^2
    "max_servo_step": 0.02,             # m
    "max_servo_rotation_step": math.radians(5.0),  # rad
    "max_tool_tilt": math.pi,           # rad
    "staleness_timeout": 1.0,           # s: stale state must be caught within 1 s
    "max_servo_period": 0.5,            # s
    "max_deflection": 32767.0,          # counts (int16 full scale)
    "overload_samples": 2000,           # samples (one 1-Hz whisk cycle at 2 kHz)
}

#: Number of orientations checked along a linear move (slerp samples).
_PATH_SAMPLES = 8


_VECTOR_FIELDS = frozenset({"workspace_min", "workspace_max", "tool_reference_axis"})
#: the declared check of every scalar limit (read by whisker_io.validation.validate_fields): a finite
#: number > 0 (a limit given as a sequence would skip every check), kept as float / int; the reader's
#: refusal (NaN, text, an array) re-raised as a ConfigError
_LIMIT = dict(above=0, store=True, reader_message="SafetyEnvelope: {error}",
              message="{name} must be {want}, got {value!r}")
#: a limit with a hard ceiling (HARD_CEILINGS) as its maximum
_CEILING = dict(_LIMIT, message="{name} must be {want} (its hard ceiling: the safety envelope cannot be widened "
                                "beyond it), got {value!r}")
_CEILED = dict(_CEILING, reader=finite_scalar)


def _command_scalar(value, name: str) -> float:
    """A finite command value; anything else is refused (nothing is sent)."""
    try:
        return finite_scalar(value, name)
    except InvalidInputError as exc:
        raise SafetyViolationError(f"refused: {exc}") from None


#: Slowest speed a move command may ask for (m/s or rad/s): slower, a 1 m move would take
#: more than 11 days and its duration overflows; a denormal speed is refused, not run.
MIN_COMMAND_SPEED = 1e-6


@dataclass(frozen=True)
class SafetyEnvelope(ConfigDataclass):
    """Limits every arm command must satisfy (all in SI units, base frame).

    Parameters
    ----------
    workspace_min, workspace_max : tuple of 3 float
        Corners of the axis-aligned workspace box for the tool-centre point,
        metres in the robot base frame. Default x, y in [-0.5, 0.5] m,
        z in [0.05, 0.7] m (inside the UR5's 0.85 m reach).
    tool_reference_axis : tuple of 3 float
        Direction (base frame) the tool z-axis is nominally pointing;
        default straight down ``(0, 0, -1)``.
    max_tool_tilt : float
        Largest angle (rad) between the tool z-axis and the reference axis;
        default pi/2.
    max_tcp_speed : float
        Largest linear tool speed (m/s) of a move or implied by servo steps;
        default 0.1.
    max_tcp_acceleration : float
        Largest linear tool acceleration (m/s^2); default 0.5.
    max_joint_speed : float
        Largest joint speed (rad/s) for joint moves and the largest observed
        joint speed tolerated in the arm state; default 0.1 as in Sec 2.2.1.
    max_joint_acceleration : float
        Largest joint acceleration (rad/s^2); default 0.5.
    max_servo_step : float
        Largest translation (m) between successive servo targets; default 0.002.
    max_servo_rotation_step : float
        Largest rotation (rad) between successive servo targets; default 1 deg.
    min_servo_period, max_servo_period : float
        Allowed servo time step (s); default [0.002, 0.1].
    max_deflection : float
        Deflection overload level in ADC counts; default 2000, 98 % of the
        2047-count sensor maximum (the retract-at-maximum RCP threshold of
        Sec 4.1.1).
    overload_samples : int
        A deflection at or above ``max_deflection`` for this many consecutive
        samples is an overload and stops the arm; default 200 (0.1 s at
        2 kHz). Decision: RCP / retract-at-maximum frees a whisker within a
        few samples of reaching the maximum, so a whisker that stays there is
        pinned - the arm is pushing the array into the object.
    staleness_timeout : float
        Largest age (s) of the arm state before it is stale; default 0.25,
        ceiling 1.0 so a dropped link is always caught within 1 s.
    joint_speed_tolerance : float
        Factor (>= 1) on ``max_joint_speed`` for *observed* joint speeds
        (controller overshoot); default 1.25.

    Raises
    ------
    ConfigError
        A limit is not a finite number (a scalar limit given as a sequence, a
        string, NaN/inf), non-positive, above its hard ceiling, a box corner or
        axis is not 3 finite numbers, or the box is empty.
    """

    workspace_min: tuple[float, float, float] = (-0.5, -0.5, 0.05)
    workspace_max: tuple[float, float, float] = (0.5, 0.5, 0.7)
    tool_reference_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    max_tool_tilt: float = checked(math.pi / 2, float, maximum=HARD_CEILINGS["max_tool_tilt"], **_CEILED)
    max_tcp_speed: float = checked(0.1, float, maximum=HARD_CEILINGS["max_tcp_speed"], **_CEILED)
    max_tcp_acceleration: float = checked(0.5, float, maximum=HARD_CEILINGS["max_tcp_acceleration"], **_CEILED)
    max_joint_speed: float = checked(0.1, float, maximum=HARD_CEILINGS["max_joint_speed"], **_CEILED)
    max_joint_acceleration: float = checked(0.5, float, maximum=HARD_CEILINGS["max_joint_acceleration"], **_CEILED)
    max_servo_step: float = checked(0.002, float, maximum=HARD_CEILINGS["max_servo_step"], **_CEILED)
    max_servo_rotation_step: float = checked(math.radians(1.0), float,
                                             maximum=HARD_CEILINGS["max_servo_rotation_step"], **_CEILED)
    min_servo_period: float = checked(0.002, float, reader=finite_scalar, **_LIMIT)
    max_servo_period: float = checked(0.1, float, maximum=HARD_CEILINGS["max_servo_period"], **_CEILED)
    max_deflection: float = checked(2000.0, float, maximum=HARD_CEILINGS["max_deflection"], **_CEILED)
    overload_samples: int = checked(200, int, maximum=HARD_CEILINGS["overload_samples"], reader=whole_number,
                                    **_CEILING)
    staleness_timeout: float = checked(0.25, float, maximum=HARD_CEILINGS["staleness_timeout"], **_CEILED)
    joint_speed_tolerance: float = checked(1.25, float, reader=finite_scalar, **dict(_LIMIT, above=None, minimum=1.0))

    def __post_init__(self) -> None:
        vectors = {name: getattr(self, name) for name in _VECTOR_FIELDS}  # as given (validate_fields makes lists tuples)
        validate_fields(self)  # every scalar limit: finite, > 0, under its ceiling; stored as float / int
        for name in ("workspace_min", "workspace_max", "tool_reference_axis"):
            try:
                corner = tuple(float(v) for v in finite_vector(vectors[name], 3, name))
            except InvalidInputError as exc:
                raise ConfigError(f"SafetyEnvelope: {exc}") from None
            object.__setattr__(self, name, corner)
        if not all(lo < hi for lo, hi in zip(self.workspace_min, self.workspace_max)):
            raise ConfigError("workspace_min must be < workspace_max on every axis; got "
                                    f"{self.workspace_min} / {self.workspace_max}")
        if np.linalg.norm(self.tool_reference_axis) < 1e-9:
            raise ConfigError("tool_reference_axis must be a non-zero vector")
        if self.min_servo_period > self.max_servo_period:
            raise ConfigError("min_servo_period must be <= max_servo_period")

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the envelope as a JSON object of its fields (SI units, as the fields' names say).

        A lab keeps its cell's limits in such a file and gives it to the hardware examples
        (``--envelope FILE``); :meth:`load` reads it back to an equal envelope. The file is
        written whole or not at all (:func:`whisker_io.persistence.write_atomically`).
        """
        from whisker_io.persistence import write_atomically

        text = json.dumps(dataclasses.asdict(self), indent=2) + "\n"
        write_atomically(path, lambda fh: fh.write(text.encode("utf-8")))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "SafetyEnvelope":
        """Read an envelope written by :meth:`save`, or by hand: a JSON object whose keys are
        field names; a field left out keeps its default (e.g. ``{"workspace_min": [0.2, -0.4,
        0.02], "workspace_max": [0.8, 0.4, 0.6], "max_tool_tilt": 2.0}``).

        Raises
        ------
        FileNotFoundError
            No such file.
        CorruptFileError
            The file is not JSON, or not one JSON object (message names the file).
        ConfigError
            A key names no field (:class:`~whisker_io.errors.UnknownFieldError`, with the nearest
            field's name), or a value breaks its limit (message names the field and the file).
        """
        return cls.from_limits(read_limits(path), source=os.fspath(path))

    @classmethod
    def from_limits(cls, limits: Mapping[str, Any], *, source: str = "") -> "SafetyEnvelope":
        """The envelope of ``limits`` (field name -> value, as :func:`read_limits` gives them; a field left out
        keeps its default). ``source`` (the file) begins every error message.

        Raises
        ------
        ConfigError
            A null value, a key that names no field (:class:`~whisker_io.errors.UnknownFieldError`) or a value
            that breaks its limit.
        """
        where = f"{source}: " if source else ""
        nulls = [k for k, v in limits.items() if v is None]
        if nulls:  # JSON's null is no limit (it would be read as NaN)
            raise ConfigError(f"{where}{', '.join(nulls)}: null is no limit; give a number or leave the field out "
                              "for its default")
        try:
            return cls(**limits)
        except ConfigError as exc:
            raise type(exc)(f"{where}{exc}") from None

    # ------------------------------------------------------------------ poses
    def _tilt(self, rotation: Rotation) -> np.ndarray:
        ref = np.asarray(self.tool_reference_axis, dtype=float)
        ref = ref / np.linalg.norm(ref)
        axes = np.atleast_2d(rotation.apply([0.0, 0.0, 1.0]))
        return np.arccos(np.clip(axes @ ref, -1.0, 1.0))

    def check_pose(self, target: PoseLike) -> Pose:
        """Refuse a target outside the workspace box or tilted too far.

        Returns
        -------
        Pose
            The target, unchanged (converted to a :class:`Pose` if needed).

        Raises
        ------
        SafetyViolationError
            Non-finite or malformed pose, a UR rotation vector longer than
            2 pi, position outside the box, tilt above ``max_tool_tilt``.
        """
        try:
            pose = as_pose(target)
        except InvalidInputError as exc:
            raise SafetyViolationError(f"refused: {exc}") from exc
        if not isinstance(target, Pose) and np.shape(target) == (6,):
            # a UR rotation vector longer than 2 pi is numerically meaningless
            # (cos/sin of a huge angle): the robot may read it differently from us
            angle = math.hypot(*(float(v) for v in np.asarray(target, dtype=float)[3:]))
            if not angle <= 2 * math.pi:
                raise SafetyViolationError(
                    f"refused: rotation vector of length {angle:.3g} rad; give |r| <= 2 pi")
        lo = np.asarray(self.workspace_min)
        hi = np.asarray(self.workspace_max)
        p = pose.position_m
        if np.any(p < lo) or np.any(p > hi):
            raise SafetyViolationError(
                f"refused: target position {np.round(p, 4).tolist()} m is outside the "
                f"workspace box {list(self.workspace_min)}..{list(self.workspace_max)} m")
        tilt = float(self._tilt(pose.rotation)[0])
        if tilt > self.max_tool_tilt:
            raise SafetyViolationError(
                f"refused: tool tilt {math.degrees(tilt):.1f} deg exceeds "
                f"{math.degrees(self.max_tool_tilt):.1f} deg")
        return pose

    def _check_range(self, value, name: str, limit: float, lower: float = 0.0) -> float:
        v = _command_scalar(value, name)
        if not lower < v <= limit:
            raise SafetyViolationError(f"refused: {name}={v} outside ({lower}, {limit}]")
        return v

    def check_move_linear(self, current: Optional[Pose], target: PoseLike, speed: float,
                          acceleration: float) -> Pose:
        """Check a linear move (``moveL``) from ``current`` to ``target``.

        The box is convex, so a straight line between two inside points stays
        inside; orientations along the way are sampled by slerp and each is
        checked for tilt. ``current`` may be None (no state yet).

        Returns the target unchanged; raises :class:`SafetyViolationError`.
        """
        self._check_range(speed, "TCP speed (m/s)", self.max_tcp_speed, MIN_COMMAND_SPEED)
        self._check_range(acceleration, "TCP acceleration (m/s^2)", self.max_tcp_acceleration)
        pose = self.check_pose(target)
        if current is not None:
            rots = Rotation.concatenate([current.rotation, pose.rotation])
            path = Slerp([0.0, 1.0], rots)(np.linspace(0.0, 1.0, _PATH_SAMPLES))
            tilts = self._tilt(path)
            if np.any(tilts > self.max_tool_tilt) and self._tilt(current.rotation)[0] <= self.max_tool_tilt:
                raise SafetyViolationError(
                    f"refused: orientation path tilts to {math.degrees(tilts.max()):.1f} deg "
                    f"(limit {math.degrees(self.max_tool_tilt):.1f} deg)")
        return pose

    def check_servo(self, previous: Pose, target: PoseLike, dt: float) -> Pose:
        """Check one servo step (``servoL``) from the previous target.

        Parameters
        ----------
        previous : Pose
            Previous servo target, or the current pose for the first step.
        target : PoseLike
            New target.
        dt : float
            Servo period in s, within [min_servo_period, max_servo_period].

        Returns the target unchanged. Refuses a step larger than
        ``max_servo_step`` / ``max_servo_rotation_step`` or whose implied
        speed ``step / dt`` exceeds ``max_tcp_speed``.
        """
        period = _command_scalar(dt, "servo period dt (s)")
        if not (self.min_servo_period <= period <= self.max_servo_period):
            raise SafetyViolationError(
                f"refused: servo period {period} s outside "
                f"[{self.min_servo_period}, {self.max_servo_period}] s")
        pose = self.check_pose(target)
        step, rot = previous.distance_to(pose)
        if step > self.max_servo_step:
            raise SafetyViolationError(
                f"refused: servo step {step * 1e3:.2f} mm exceeds {self.max_servo_step * 1e3:.2f} mm")
        if rot > self.max_servo_rotation_step:
            raise SafetyViolationError(
                f"refused: servo rotation step {math.degrees(rot):.2f} deg exceeds "
                f"{math.degrees(self.max_servo_rotation_step):.2f} deg")
        if step / period > self.max_tcp_speed:
            raise SafetyViolationError(
                f"refused: servo step implies {step / period:.3f} m/s > {self.max_tcp_speed} m/s")
        return pose

    def check_move_joints(self, q_target, speed: float, acceleration: float) -> np.ndarray:
        """Check a joint move (``moveJ``): 6 finite angles within +-2 pi rad,
        speed <= ``max_joint_speed`` rad/s, acceleration <= the limit.

        Returns the joint target, shape (6,), unchanged.
        """
        self._check_range(speed, "joint speed (rad/s)", self.max_joint_speed, MIN_COMMAND_SPEED)
        self._check_range(acceleration, "joint acceleration (rad/s^2)", self.max_joint_acceleration)
        try:
            q = np.array(q_target, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise SafetyViolationError(f"refused: joint target must be 6 numbers; got {q_target!r}") from exc
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            raise SafetyViolationError(f"refused: joint target must be 6 finite angles; got {q.tolist()}")
        if np.any(np.abs(q) > 2 * math.pi):
            raise SafetyViolationError(f"refused: joint target {q.tolist()} rad beyond +-2 pi")
        return q

    # ----------------------------------------------------------- observations
    def check_joint_speeds(self, qd) -> None:
        """Raise :class:`SafetyViolationError` if an observed joint speed (rad/s)
        exceeds ``max_joint_speed * joint_speed_tolerance`` or is non-finite."""
        qd = np.asarray(qd, dtype=float)
        limit = self.max_joint_speed * self.joint_speed_tolerance
        if not np.all(np.isfinite(qd)) or np.any(np.abs(qd) > limit):
            raise SafetyViolationError(
                f"joint speeds {np.round(qd, 4).tolist()} rad/s exceed {limit:.3f} rad/s; arm stopped")

    def check_deflection(self, deflection) -> None:
        """Raise :class:`SafetyViolationError` on deflection overload.

        Parameters
        ----------
        deflection : array_like, shape (..., T)
            x/y deflection traces in ADC counts, time along the last axis
            (e.g. shape (36, 2000): x and y of 18 modules over one cycle).
            Overload: some trace stays at ``|d|`` >= ``max_deflection`` for
            ``overload_samples`` consecutive samples. Non-finite values count
            as overload (a broken sensor must not be trusted).
        """
        d = np.asarray(deflection, dtype=float)
        if d.size == 0:
            return
        if not np.all(np.isfinite(d)):
            raise SafetyViolationError("deflection contains NaN/inf: sensor fault; arm stopped")
        over = np.abs(d.reshape(-1, d.shape[-1])) >= self.max_deflection
        edges = np.diff(np.pad(over, ((0, 0), (1, 1))).astype(np.int8), axis=1)
        runs = np.flatnonzero(edges.ravel() == -1) - np.flatnonzero(edges.ravel() == 1)
        longest = int(runs.max()) if runs.size else 0
        if longest >= self.overload_samples:
            raise SafetyViolationError(
                f"deflection overload: {longest} consecutive samples at >= "
                f"{self.max_deflection:.0f} counts (limit {self.overload_samples}); the array is "
                "pressed into an object; arm stopped")

    def check_fresh(self, age: float) -> None:
        """Raise :class:`StaleStateError` if the arm state is older than
        ``staleness_timeout`` seconds."""
        if not age <= self.staleness_timeout:
            raise StaleStateError(
                f"arm state is {age:.3f} s old (limit {self.staleness_timeout} s): the robot "
                "link has stalled or dropped; check the network cable and the controller")


def read_limits(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The safety limits a JSON file holds, field name -> value, unchecked (:meth:`SafetyEnvelope.from_limits`
    checks them; :meth:`SafetyEnvelope.load` does both).

    Raises
    ------
    FileNotFoundError
        No such file.
    CorruptFileError
        The file is not JSON, or not one JSON object (the message names the file).
    """
    try:
        with open(path, encoding="utf-8-sig") as fh:
            data: Any = json.load(fh)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CorruptFileError(f"{os.fspath(path)}: not a JSON file of safety limits ({exc})") from None
    if not isinstance(data, dict):
        raise CorruptFileError(f"{os.fspath(path)}: a JSON object of safety limits (field: value) was expected, "
                               f"got {type(data).__name__}")
    return data

