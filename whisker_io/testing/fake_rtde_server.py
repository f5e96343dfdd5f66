"""A fake UR RTDE server for tests, run as a *separate process* on 127.0.0.1.

It speaks enough of the Universal Robots Real-Time Data Exchange protocol
(RTDE, TCP port 30004, protocol version 2) for ``ur_rtde``'s unmodified
``RTDEReceiveInterface`` to connect and receive a stream of robot states:

* ``V`` - request: uint16 protocol version; reply: uint8 accepted (1)
* ``v`` - request: (empty); reply: 4 x uint32 major, minor, bugfix, build
* ``O`` - request: float64 frequency + ``name,name,..``; reply: uint8 recipe id + ``TYPE,TYPE,...``
* ``I`` - request: ``name,name,...``; reply: uint8 recipe id + ``TYPE,...``
* ``S`` - request: (empty); reply: uint8 accepted, then data packages follow
* ``P`` - request: (empty); reply: uint8 accepted, data packages stop
* ``U`` - server -> client data package: uint8 recipe id + values, big-endian

Every package starts with a 3-byte header: big-endian uint16 total size
(header included) and a uint8 type. Values in a data package are packed in
recipe order, big-endian: DOUBLE ``d``, VECTOR3D ``3d``, VECTOR6D ``6d``,
INT32 ``i``, UINT32 ``I``, VECTOR6INT32 ``6i``, VECTOR6UINT32 ``6I``,
UINT64 ``Q``, UINT8 ``B``, BOOL ``?``.

Why a separate process: the ``ur_rtde`` constructor is a C++ call that holds
the Python interpreter lock while it blocks on the socket, so a server in a
thread of the same interpreter can never answer it (deadlock).

Modes (``--mode``):

``stream``
    Normal: answer the handshake and stream states at the requested frequency.
    The TCP pose moves slowly on a circle of radius ``--radius`` m around
    ``--centre`` so a client can see it change; ``timestamp`` advances by
    ``1/frequency`` per package.
``silent``
    Accept connections and never answer (a hung controller), for the probe test.
``freeze``
    Answer the handshake, stream ``--packages`` packages, then keep the socket
    open without sending anything (a link that stalls without closing).

On start it prints ``READY <port>`` on stdout (and flushes) once listening, so
a parent waits on that line instead of sleeping (``--port 0`` picks a free
port). It binds 127.0.0.1 only. :func:`fake_rtde_server` runs it as a child
process in a ``with`` block.

Run: ``python -m whisker_io.testing.fake_rtde_server --port 30004``.

For tests that need no socket at all, :class:`FakeReceiveInterface` and
:class:`FakeControlInterface` stand in for ur-rtde's interfaces in-process
(``URArm(receive_factory=..., control_factory=...)``).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import socket
import struct
import subprocess
import sys
import threading
import time
from typing import Iterator

from whisker_io.command_line import CommandParser
from whisker_io.errors import CansimError

__all__ = ["RTDE_PORT", "TYPE_FORMATS", "variable_type", "main", "FakeServerError",
           "fake_rtde_server", "FakeReceiveInterface", "FakeControlInterface"]


#: TCP port of the RTDE interface on a UR controller (fixed by ur_rtde).
RTDE_PORT = 30004

#: struct format (without byte order) of each RTDE type.
TYPE_FORMATS = {
    "DOUBLE": "d",
    "VECTOR3D": "3d",
    "VECTOR6D": "6d",
    "INT32": "i",
    "UINT32": "I",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
    "UINT64": "Q",
    "UINT8": "B",
    "BOOL": "?",
}

_VECTOR6D = {
    "target_q", "target_qd", "target_qdd", "target_current", "target_moment",
    "actual_q", "actual_qd", "actual_current", "joint_control_output",
    "actual_TCP_pose", "actual_TCP_speed", "actual_TCP_force", "target_TCP_pose",
    "target_TCP_speed", "joint_temperatures", "actual_joint_voltage",
    "ft_raw_wrench", "actual_current_window",
}
_DOUBLE = {
    "timestamp", "actual_execution_time", "speed_scaling", "target_speed_fraction",
    "actual_momentum", "actual_main_voltage", "actual_robot_voltage",
    "actual_robot_current", "standard_analog_input0", "standard_analog_input1",
    "standard_analog_output0", "standard_analog_output1", "tool_analog_input0",
    "tool_analog_input1", "tool_output_current", "tool_temperature", "payload",
}
_INT32 = {"robot_mode", "safety_mode", "tool_mode"}
_UINT32 = {"runtime_state", "robot_status_bits", "safety_status_bits", "safety_status",
           "analog_io_types", "io_current"}
_UINT64 = {"actual_digital_input_bits", "actual_digital_output_bits"}


def variable_type(name: str) -> str:
    """RTDE type name of an output/input variable, ``"NOT_FOUND"`` if unknown."""
    if name in _VECTOR6D:
        return "VECTOR6D"
    if name in _DOUBLE or name.startswith("output_double_register_") \
            or name.startswith("input_double_register_"):
        return "DOUBLE"
    if name in _INT32 or name.startswith("output_int_register_") \
            or name.startswith("input_int_register_"):
        return "INT32"
    if name in _UINT32 or name.startswith("input_bit_registers"):
        return "UINT32"
    if name in _UINT64:
        return "UINT64"
    if name in ("joint_mode",):
        return "VECTOR6INT32"
    if name in ("actual_tool_accelerometer", "payload_cog"):
        return "VECTOR3D"
    if name.startswith("output_bit_register") or name.startswith("input_bit_register_"):
        return "BOOL"
    if name in ("speed_slider_mask", "standard_digital_output_mask",
                "standard_digital_output", "tool_digital_output_mask",
                "tool_digital_output"):
        return "UINT8" if "digital" in name else "UINT32"
    if name == "speed_slider_fraction":
        return "DOUBLE"
    return "NOT_FOUND"


def _pack(ptype: str, payload: bytes) -> bytes:
    return struct.pack(">HB", 3 + len(payload), ord(ptype)) + payload


def _recv_exact(conn: socket.socket, n: int) -> bytes | None:
    buf = b""
    while len(buf) < n:
        chunk = conn.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf


class _State:
    """The simulated robot: a TCP pose moving on a circle, joints drifting."""

    def __init__(self, centre: tuple[float, float, float], radius: float, period: float):
        self.centre = centre
        self.radius = radius
        self.period = period

    def value(self, name: str, t: float):
        phase = 2.0 * math.pi * t / self.period
        if name == "timestamp":
            return (t,)
        if name in ("actual_TCP_pose", "target_TCP_pose"):
            cx, cy, cz = self.centre
            return (cx + self.radius * math.cos(phase), cy + self.radius * math.sin(phase),
                    cz, 0.0, math.pi, 0.0)
        if name in ("actual_q", "target_q"):
            return tuple(0.1 * math.sin(phase) + k * 0.2 for k in range(6))
        if name in ("robot_mode",):
            return (7,)  # RUNNING
        if name in ("safety_mode",):
            return (1,)  # NORMAL
        if name == "speed_scaling" or name == "target_speed_fraction":
            return (1.0,)
        return None  # zeros of the right type


def _values(names: list[str], types: list[str], state: _State, t: float) -> bytes:
    out = [b"\x01"]  # recipe id
    for name, typ in zip(names, types):
        fmt = TYPE_FORMATS[typ]
        v = state.value(name, t)
        if v is None:
            count = int(fmt[:-1]) if len(fmt) > 1 else 1
            v = (False,) * count if fmt[-1] == "?" else (0,) * count
        out.append(struct.pack(">" + fmt, *v))
    return b"".join(out)


def _serve_client(conn: socket.socket, args: argparse.Namespace, state: _State,
                  stop: threading.Event) -> None:
    names: list[str] = []
    types: list[str] = []
    frequency = 125.0
    streaming = threading.Event()
    sender: threading.Thread | None = None
    lock = threading.Lock()

    def stream() -> None:
        k = 0
        t0 = time.monotonic()
        while not stop.is_set() and streaming.is_set():
            if args.mode == "freeze" and k >= args.packages:
                streaming.wait(3600)  # stall forever with the socket open
                return
            t = k / frequency
            pkg = _pack("U", _values(names, types, state, t))
            try:
                with lock:
                    conn.sendall(pkg)
            except OSError:
                return
            k += 1
            delay = t0 + k / frequency - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    try:
        while not stop.is_set():
            header = _recv_exact(conn, 3)
            if header is None:
                return
            size, ptype = struct.unpack(">HB", header)
            body = _recv_exact(conn, size - 3) if size > 3 else b""
            if body is None:
                return
            cmd = chr(ptype)
            if cmd == "V":
                reply = _pack("V", b"\x01")
            elif cmd == "v":
                reply = _pack("v", struct.pack(">IIII", 5, 9, 0, 0))
            elif cmd == "O":
                frequency = struct.unpack(">d", body[:8])[0] if len(body) >= 8 else 125.0
                if not (0 < frequency <= 500):
                    frequency = 125.0
                names = [n for n in body[8:].decode("ascii").split(",") if n]
                types = [variable_type(n) for n in names]
                reply = _pack("O", b"\x01" + ",".join(types).encode("ascii"))
            elif cmd == "I":
                in_names = [n for n in body.decode("ascii").split(",") if n]
                in_types = [variable_type(n) for n in in_names]
                reply = _pack("I", b"\x02" + ",".join(in_types).encode("ascii"))
            elif cmd == "S":
                ok = "NOT_FOUND" not in types
                reply = _pack("S", b"\x01" if ok else b"\x00")
                if ok and not streaming.is_set():
                    streaming.set()
                    sender = threading.Thread(target=stream, daemon=True)
                    with lock:
                        conn.sendall(reply)
                    sender.start()
                    continue
            elif cmd == "P":
                streaming.clear()
                reply = _pack("P", b"\x01")
            else:  # inputs from the client (data packages) are ignored
                continue
            with lock:
                conn.sendall(reply)
    except OSError:
        return
    finally:
        streaming.clear()
        try:
            conn.close()
        except OSError:
            pass


class FakeServerError(CansimError, RuntimeError):
    """The fake server could not start (e.g. the port is taken); part of the one error tree."""


@contextlib.contextmanager
def fake_rtde_server(mode: str = "stream", port: int = RTDE_PORT,
                     extra_args: tuple[str, ...] = (),
                     bind_retry_s: float = 3.0) -> Iterator[tuple[subprocess.Popen, int]]:
    """Run the fake server in a child process for the duration of a ``with``.

    ur-rtde only talks to port 30004, so a server of an earlier test that is still
    shutting down can hold it for a moment: a failed bind is retried for
    ``bind_retry_s`` seconds before giving up.

    The child runs this file as a script (no package import, so it starts
    fast) and the context waits for its ``READY <port>`` line, not a sleep.
    Yields ``(process, port)``; the process is killed on exit. Kill it
    earlier (``process.kill()``) to simulate a controller dying mid-stream.

    Raises
    ------
    FakeServerError
        The port is taken or the child died before listening.
    """
    deadline = time.monotonic() + bind_retry_s
    while True:
        proc = subprocess.Popen([sys.executable, __file__, "--mode", mode, "--port", str(port),
                                 *extra_args], stdout=subprocess.PIPE, text=True)
        line = proc.stdout.readline() if proc.stdout else ""
        if line.startswith("READY") or not line.startswith("BIND-FAILED") or time.monotonic() > deadline:
            break
        # the fixed RTDE port is still held by a process that is going away: try again shortly
        proc.wait()
        if proc.stdout:
            proc.stdout.close()
        time.sleep(0.1)
    try:
        if not line.startswith("READY"):
            raise FakeServerError(f"fake RTDE server did not start on 127.0.0.1:{port}: "
                                  f"{line.strip() or 'exited'}")
        yield proc, int(line.split()[1])
    finally:
        proc.kill()
        proc.wait()
        if proc.stdout:
            proc.stdout.close()


class FakeReceiveInterface:
    """In-process stand-in for ``rtde_receive.RTDEReceiveInterface`` (no socket).

    Its ``timestamp`` advances by ``dt`` on every read unless :attr:`frozen`
    (a stalled link); :attr:`connected` can be cleared (a dropped link).
    Pass ``receive_factory=lambda host: FakeReceiveInterface(...)`` to ``URArm``.

    Parameters
    ----------
    tcp_pose : sequence of 6 float
        UR TCP pose returned by ``getActualTCPPose`` (m, rotation vector rad);
        default 0.4 m forward, 0.4 m up, tool pointing down.
    dt : float
        Controller time step per read, s.
    """

    def __init__(self, tcp_pose=(0.4, 0.0, 0.4, 0.0, math.pi, 0.0), dt: float = 0.002) -> None:
        self.tcp_pose = list(tcp_pose)
        self.dt = dt
        self.t = 0.0
        self.frozen = False
        self.connected = True
        self.qd = [0.0] * 6  # joint speeds reported, rad/s

    def isConnected(self) -> bool:
        return self.connected

    def getTimestamp(self) -> float:
        if not self.frozen:
            self.t += self.dt
        return self.t

    def getActualTCPPose(self) -> list[float]:
        return list(self.tcp_pose)

    def getActualQ(self) -> list[float]:
        return [0.0] * 6

    def getActualQd(self) -> list[float]:
        return list(self.qd)

    def disconnect(self) -> None:
        self.connected = False


class FakeControlInterface:
    """In-process stand-in for ``rtde_control.RTDEControlInterface`` that records
    every call reaching "the robot" in :attr:`calls` as ``(name, args)``.

    Parameters
    ----------
    ok : bool
        Return value of the motion commands (False: the controller refuses).
    """

    def __init__(self, ok: bool = True) -> None:
        self.ok = ok
        self.calls: list[tuple[str, tuple]] = []

    def _record(self, name: str, args: tuple) -> bool:
        self.calls.append((name, args))
        return self.ok

    def moveL(self, *args) -> bool:
        return self._record("moveL", args)

    def servoL(self, *args) -> bool:
        return self._record("servoL", args)

    def moveJ(self, *args) -> bool:
        return self._record("moveJ", args)

    def servoStop(self, *args) -> bool:
        self.calls.append(("servoStop", args))
        return True

    def stopL(self, *args) -> None:
        self.calls.append(("stopL", args))

    def disconnect(self) -> None:
        self.calls.append(("disconnect", ()))

    def motions(self) -> list[tuple[str, tuple]]:
        """The motion commands received (moveL, servoL, moveJ), in order."""
        return [c for c in self.calls if c[0] in ("moveL", "servoL", "moveJ")]


def main(argv: list[str] | None = None) -> int:
    """Run the fake server until killed. See the module docstring for options."""
    p = CommandParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, default=RTDE_PORT)
    p.add_argument("--mode", choices=("stream", "silent", "freeze"), default="stream")
    p.add_argument("--packages", type=int, default=50,
                   help="freeze mode: number of packages streamed before stalling")
    p.add_argument("--centre", type=float, nargs=3, default=(0.4, 0.0, 0.4))
    p.add_argument("--radius", type=float, default=0.05)
    p.add_argument("--period", type=float, default=20.0)
    args = p.parse_args(argv)
    state = _State(tuple(args.centre), args.radius, args.period)
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        srv.bind(("127.0.0.1", args.port))
    except OSError as exc:
        sys.stdout.write(f"BIND-FAILED {exc}\n")
        sys.stdout.flush()
        return 2
    srv.listen(8)
    sys.stdout.write(f"READY {srv.getsockname()[1]}\n")
    sys.stdout.flush()
    stop = threading.Event()
    held: list[socket.socket] = []
    try:
        while True:
            conn, _ = srv.accept()
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            if args.mode == "silent":
                held.append(conn)  # keep it open, never answer
                continue
            threading.Thread(target=_serve_client, args=(conn, args, state, stop),
                             daemon=True).start()
    except KeyboardInterrupt:
        return 0
    finally:
        stop.set()
        srv.close()


if __name__ == "__main__":  # pragma: no cover - run as a subprocess
    sys.exit(main())
