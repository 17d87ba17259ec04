"""Links between the harness and the target: a serial port (pyserial) or CAN (python-can:
`slcan` over a serial device, or `socketcan` on a real interface).

For a local replay the harness creates a pseudo-terminal pair (os.openpty): the loop
program inherits the master side as `fd:N`; the harness opens the slave side by its path
(/dev/pts/N) with pyserial or python-can's slcan interface, exactly as it would open
/dev/ttyUSB0 on a bench. A reader thread timestamps every chunk/message as it arrives
(time.perf_counter_ns, CLOCK_MONOTONIC) so latency can be computed afterwards.
"""

from __future__ import annotations

import os
import select
import socket
import threading
import time
import tty
from dataclasses import dataclass, field

import can
import serial

from gyrodrift.errors import GyrodriftValueError

__all__ = [
    "CAN_FRAME_BITS",
    "UART_BITS_PER_BYTE",
    "CanLink",
    "Capture",
    "PtyPair",
    "SerialLink",
    "sleep_until_ns",
]

# Nominal bits of a classic CAN data frame with an 11-bit ID and 8 data bytes, without
# stuffing: SOF 1 + ID 11 + RTR/IDE/r0 3 + DLC 4 + data 64 + CRC 15 + delimiters/ACK/EOF 13
# + intermission 3 (ISO 11898-1 frame format).
CAN_FRAME_BITS = 111
# 8N1 UART: start + 8 data + stop bits per byte.
UART_BITS_PER_BYTE = 10


@dataclass
class PtyPair:
    """A pseudo-terminal pair: the loop takes the master side, the harness opens the slave by
    its path.

    Examples
    --------
    >>> pty = PtyPair.open()
    >>> _ = os.write(pty.master_fd, b"abc")
    >>> os.read(pty.slave_fd, 3), pty.slave_path.startswith("/dev/pts/")
    (b'abc', True)
    >>> pty.close()
    """
    master_fd: int
    slave_fd: int
    slave_path: str

    @classmethod
    def open(cls) -> PtyPair:
        master, slave = os.openpty()
        tty.setraw(slave)
        return cls(master, slave, os.ttyname(slave))

    @classmethod
    def open_socketpair(cls) -> PtyPair:
        """A connected AF_UNIX stream pair instead of a pty (diagnostics only): the bytes do
        not pass through the kernel's tty layer, whose flip-buffer work runs at normal
        priority. The harness side is named "fd:N" (SerialLink opens it without pyserial)."""
        a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        master, slave = a.detach(), b.detach()
        return cls(master, slave, f"fd:{slave}")

    def close_master(self) -> None:
        if self.master_fd >= 0:
            os.close(self.master_fd)
            self.master_fd = -1

    def close(self) -> None:
        self.close_master()
        if self.slave_fd >= 0:
            os.close(self.slave_fd)
            self.slave_fd = -1


@dataclass
class Capture:
    """Everything the reader thread saw: (arrival_ns, payload) in arrival order.

    Examples
    --------
    >>> c = Capture(chunks=[(0, b"ab"), (5, b"cde")])
    >>> c.byte_count
    5
    """

    chunks: list[tuple[int, bytes]] = field(default_factory=list)
    messages: list[tuple[int, can.Message]] = field(default_factory=list)
    error: str = ""

    @property
    def byte_count(self) -> int:
        return sum(len(c) for _, c in self.chunks)


def set_thread_realtime(priority: int) -> str:
    """SCHED_FIFO at `priority` for the calling thread only (on Linux the policy belongs to
    the thread, and pid 0 names the caller). Returns what the kernel reports afterwards,
    'SCHED_FIFO 70', or 'refused: <reason>' (no CAP_SYS_NICE / RLIMIT_RTPRIO, not Linux)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        policy = os.sched_getscheduler(0)
        got = os.sched_getparam(0).sched_priority
    except (OSError, AttributeError) as exc:
        return f"refused: {exc}"
    if policy != os.SCHED_FIFO:
        return f"refused: policy {policy} after the request"
    return f"SCHED_FIFO {got}"


def set_thread_normal() -> None:
    """Back to SCHED_OTHER for the calling thread (no-op where that is not possible)."""
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError):
        pass


class SerialLink:
    """A serial device opened with pyserial (raw 8N1); reads on a background thread, which
    runs SCHED_FIFO at `realtime_priority` when given and permitted (`receiver_realtime`
    says what it got).

    Examples
    --------
    >>> pty = PtyPair.open()
    >>> link = SerialLink(pty.slave_path, 921600)
    >>> _ = os.write(pty.master_fd, b"reply")  # what the target sends
    >>> t_end = time.monotonic() + 5.0
    >>> while link.received_bytes() < 5 and time.monotonic() < t_end:
    ...     time.sleep(0.01)
    >>> link.write(b"frame")
    >>> link.received_bytes(), os.read(pty.master_fd, 5)
    (5, b'frame')
    >>> link.close(); pty.close()
    """

    def __init__(self, path: str, baud: int, *, realtime_priority: int | None = None) -> None:
        self.port: serial.Serial | None = None
        self._fd = -1
        if path.startswith("fd:"):  # an already open descriptor (PtyPair.open_socketpair)
            self._fd = int(path[3:])
        else:
            try:
                self.port = serial.Serial(path, baudrate=baud, timeout=0, write_timeout=None)
            except (serial.SerialException, ValueError) as exc:
                raise OSError(f"cannot open serial device {path!r} at {baud} baud: {exc}"
                              ) from exc
        self.capture = Capture()
        self.bytes_sent = 0
        self.realtime_priority = realtime_priority
        self.receiver_realtime = "not requested"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_loop, name="serial-reader", daemon=True)
        self._thread.start()

    def write(self, data: bytes) -> None:
        if self.port is not None:
            self.port.write(data)  # blocks until the kernel took it all (write_timeout=None)
        else:
            view = memoryview(data)
            while view:
                view = view[os.write(self._fd, view):]
        self.bytes_sent += len(data)

    def _read_loop(self) -> None:
        if self.realtime_priority is not None:
            self.receiver_realtime = set_thread_realtime(self.realtime_priority)
        fd = self.port.fileno() if self.port is not None else self._fd
        chunks = self.capture.chunks
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([fd], [], [], 0.05)
                if not ready:
                    continue
                data = os.read(fd, 1 << 16)
                if data:
                    chunks.append((time.perf_counter_ns(), data))
        except OSError as exc:  # the other side went away
            if not self._stop.is_set():
                self.capture.error = str(exc)

    def received_bytes(self) -> int:
        return self.capture.byte_count

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        if self.port is not None:
            self.port.close()  # (an "fd:N" descriptor belongs to its PtyPair)


class CanLink:
    """python-can bus: `slcan` over a serial device (USB-CAN adapters, or a pty in tests)
    or `socketcan` on a kernel interface (can0). Never a network-backed interface.

    Examples
    --------
    >>> from gyrodrift.codecs import encode_sample
    >>> pty = PtyPair.open()  # an SLCAN adapter on a pseudo-terminal
    >>> link = CanLink("slcan", pty.slave_path)
    >>> link.send(encode_sample(1, [0.0] * 6)[0])
    >>> time.sleep(0.1)
    >>> os.read(pty.master_fd, 4096).split(b"\\r")[-2]  # the frame as an SLCAN line
    b't10080000000000000000'
    >>> link.close(); pty.close()
    """

    def __init__(self, interface: str, channel: str, *, bitrate: int = 500000,
                 tty_baud: int = 921600, realtime_priority: int | None = None) -> None:
        if interface not in ("slcan", "socketcan"):
            raise GyrodriftValueError(f"CAN interface must be 'slcan' or 'socketcan', got "
                                      f"{interface!r}")
        self.interface = interface
        try:
            if interface == "slcan":
                self.bus = can.Bus(interface="slcan", channel=channel, tty_baudrate=tty_baud,
                                   bitrate=bitrate, sleep_after_open=0)
            else:
                self.bus = can.Bus(interface="socketcan", channel=channel)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise OSError(f"cannot open CAN {interface} on {channel!r}: {exc}") from exc
        self.capture = Capture()
        self.frames_sent = 0
        self.realtime_priority = realtime_priority
        self.receiver_realtime = "not requested"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_loop, name="can-reader", daemon=True)
        self._thread.start()

    def send(self, msg: can.Message) -> None:
        self.bus.send(msg)
        self.frames_sent += 1

    def send_raw_line(self, line: bytes) -> None:
        """Bytes straight onto the adapter's serial line (slcan only): how a line error is
        injected, since python-can only ever writes well-formed lines."""
        if self.interface != "slcan":
            raise GyrodriftValueError("raw lines need the slcan interface")
        # python-can's pyserial port of the slcan bus (not in BusABC's type)
        port = self.bus.serialPortOrig  # type: ignore[attr-defined]
        port.write(line)
        port.flush()

    def _read_loop(self) -> None:
        if self.realtime_priority is not None:
            self.receiver_realtime = set_thread_realtime(self.realtime_priority)
        msgs = self.capture.messages
        try:
            while not self._stop.is_set():
                m = self.bus.recv(timeout=0.05)
                if m is not None:
                    msgs.append((time.perf_counter_ns(), m))
        except (can.CanError, OSError, ValueError) as exc:
            if not self._stop.is_set():
                self.capture.error = str(exc)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        try:
            self.bus.shutdown()
        except (can.CanError, OSError, ValueError):
            pass  # the loop may already have closed its end


def sleep_until_ns(t_ns: int, spin_ns: int = 200_000) -> None:
    """Sleep to within spin_ns of t_ns, then spin: OS sleeps overshoot by ~50-100 us.

    Examples
    --------
    >>> t = time.perf_counter_ns() + 2_000_000  # 2 ms from now
    >>> sleep_until_ns(t)
    >>> time.perf_counter_ns() >= t
    True
    """
    while True:
        rem = t_ns - time.perf_counter_ns()
        if rem <= 0:
            return
        # sleep(0) in the spin releases the GIL, so the reader thread is never starved.
        time.sleep((rem - spin_ns) * 1e-9 if rem > spin_ns else 0)
