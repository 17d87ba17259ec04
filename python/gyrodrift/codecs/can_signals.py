"""A user's own DBC: which of its signals are the IMU's six channels (and, when present, its
sequence counter and timestamp), decoding through cantools, and the decode table the C++
loop reads (include/gyrodrift/codecs/can_signal_decode.hpp).

A signal map is a small TOML file next to the vendor's DBC::

    schema = "gyrodrift.can_signals"
    version = 1
    dbc = "vendor_imu.dbc"              # relative to this file

    [channels]                          # MESSAGE.SIGNAL for gx gy gz ax ay az (all six)
    gx = "VendorImu_Rates.RateX"
    ...
    [factors]                           # optional: channel = DBC physical value * factor
    gx = 0.017453292519943295           # deg/s -> rad/s (channels are rad/s and m/s^2)
    [sequence]                          # optional: a sample counter (any width <= 16 bits)
    signal = "VendorImu_Rates.Counter"
    [timestamp]                         # optional: the IMU's own sample time
    signal = "VendorImu_Mux.TimeStamp"
    unit = "us"                         # us, ms or s (after the DBC's scale and offset)

Assembly of a sample (the same rules in Python and C++, `SignalSampleAssembler`): frames of
the mapped messages fill the sample's roles (six channels, and the sequence and timestamp
when mapped); the sample is complete when every role is filled. A frame that would fill a
role already filled drops the partial sample (counted in incomplete_samples, its frames in
frames_dropped) and starts the next one. A frame of a mapped message that carries none of
the mapped signals (another multiplexer page) is counted in ignored_frames, and so is a frame
whose multiplexer value the DBC does not define (cantools decodes nothing of it, even its
signals outside the multiplexer; also counted in undefined_page_frames); a frame shorter
than its message is counted in bad_dlc (and dropped). A sequence counter narrower than 16
bits is unwrapped into the 16-bit sample sequence (steps modulo 2**width). Accounting:
frames_in == foreign_frames + frames_used + frames_dropped + ignored_frames + pending_frames.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import cantools

from gyrodrift.errors import GyrodriftValueError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "CHANNEL_ROLES",
    "MAX_DLC",
    "MAX_PAGES",
    "ROLES",
    "TABLE_HEADER",
    "TIME_UNITS",
    "MapError",
    "SignalMap",
    "SignalRxStats",
    "SignalSample",
    "SignalSampleAssembler",
    "decode_table",
    "decode_table_text",
    "encode_sample_frames",
    "load_signal_map",
]

CHANNEL_ROLES: tuple[str, ...] = ("gx", "gy", "gz", "ax", "ay", "az")
ROLES: tuple[str, ...] = (*CHANNEL_ROLES, "seq", "time")
#: timestamp unit -> factor to microseconds
TIME_UNITS: dict[str, float] = {"us": 1.0, "ms": 1e3, "s": 1e6}
TABLE_HEADER = "gyrodrift-can-signals 1"
#: The most multiplexer pages the decode table holds for one message.
MAX_PAGES = 64
#: Classic CAN: the decoders read frames of at most 8 data bytes.
MAX_DLC = 8
SCHEMA = "gyrodrift.can_signals"


class MapError(GyrodriftValueError):
    """A signal map that cannot be used (names the file and the key or signal at fault).

    Examples
    --------
    >>> issubclass(MapError, ValueError)
    True
    >>> from gyrodrift.codecs.can_frames import load_dbc
    >>> SignalMap(load_dbc(), {"gx": SignalRef("IMU_GyroXY", "GyroX")}, "my.toml")
    Traceback (most recent call last):
    ...
    gyrodrift.codecs.can_signals.MapError: my.toml: channels gy, gz, ax, ay, az are not mapped
    """


@dataclass(frozen=True)
class SignalRef:
    message: str
    signal: str
    factor: float = 1.0


@dataclass
class SignalMap:
    """A user DBC (loaded with cantools) and the signals that make an IMU sample.

    Examples
    --------
    The project's own DBC (gyrodrift_imu.dbc) mapped as if it were a user's:

    >>> from gyrodrift.codecs.can_frames import load_dbc  # the project's own DBC as the "user's"
    >>> names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
    ...              ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ",
    ...              seq="IMU_GyroZ.Seq")
    >>> smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    >>> smap.seq_bits, sorted(hex(fid) for fid, _ in smap.messages)
    (16, ['0x100', '0x101', '0x102', '0x103'])
    """

    db: cantools.database.can.Database
    roles: dict[str, SignalRef]  # role (CHANNEL_ROLES, "seq", "time") -> signal
    source: str = ""

    def __post_init__(self) -> None:
        missing = [r for r in CHANNEL_ROLES if r not in self.roles]
        if missing:
            raise MapError(f"{self.source}: channels {', '.join(missing)} are not mapped")
        for role, ref in self.roles.items():
            if role not in ROLES:
                raise MapError(f"{self.source}: unknown role {role!r}")
            sig = self._signal(role, ref)
            msg = self.db.get_message_by_name(ref.message)
            if msg.length > MAX_DLC or getattr(msg, "is_fd", False):
                raise MapError(f"{self.source}: {role}: {ref.message} is a CAN FD message "
                               f"({msg.length} bytes); the decoders read classic CAN frames "
                               f"(at most {MAX_DLC} data bytes)")
            if sig.multiplexer_ids is not None and len(sig.multiplexer_ids) != 1:
                raise MapError(f"{self.source}: {role}: {ref.message}.{ref.signal} belongs to "
                                 f"{len(sig.multiplexer_ids)} multiplexer values; map a "
                                 "signal of one page")
            if sig.multiplexer_signal is not None:
                msg = self.db.get_message_by_name(ref.message)
                mux = msg.get_signal_by_name(sig.multiplexer_signal)
                if mux.multiplexer_signal is not None:
                    raise MapError(f"{self.source}: {role}: nested multiplexing is not "
                                     "supported")
            if not (math.isfinite(ref.factor) and ref.factor != 0):
                raise MapError(f"{self.source}: {role}: factor must be finite and non-zero")
            if role == "seq" and (sig.is_float or sig.length > 16 or sig.is_signed
                                  or sig.scale != 1 or sig.offset != 0):
                raise MapError(f"{self.source}: seq: {ref.message}.{ref.signal} must be an "
                                 "unsigned integer of at most 16 bits with scale 1, offset 0")

    def _signal(self, role: str, ref: SignalRef) -> Any:
        try:
            msg = self.db.get_message_by_name(ref.message)
        except KeyError:
            raise MapError(f"{self.source}: {role}: no message {ref.message!r} in the DBC"
                             ) from None
        try:
            return msg.get_signal_by_name(ref.signal)
        except KeyError:
            raise MapError(f"{self.source}: {role}: message {ref.message} has no signal "
                             f"{ref.signal!r}") from None

    @property
    def messages(self) -> dict[tuple[int, bool], Any]:
        """(frame id, extended) -> cantools Message, for every mapped message."""
        out = {}
        for ref in self.roles.values():
            m = self.db.get_message_by_name(ref.message)
            out[(m.frame_id, bool(m.is_extended_frame))] = m
        return out

    @property
    def seq_bits(self) -> int:
        ref = self.roles.get("seq")
        return 0 if ref is None else int(self._signal("seq", ref).length)


def load_signal_map(path: str | Path) -> SignalMap:
    """Read a signal map (TOML, module docstring) and the DBC it names.

    Examples
    --------
    >>> import tempfile
    >>> from importlib import resources
    >>> dbc = resources.files("gyrodrift") / "data" / "gyrodrift_imu.dbc"
    >>> toml = (f'schema = "gyrodrift.can_signals"\\nversion = 1\\ndbc = "{dbc}"\\n[channels]\\n'
    ...         'gx = "IMU_GyroXY.GyroX"\\ngy = "IMU_GyroXY.GyroY"\\ngz = "IMU_GyroZ.GyroZ"\\n'
    ...         'ax = "IMU_AccelXY.AccelX"\\nay = "IMU_AccelXY.AccelY"\\n'
    ...         'az = "IMU_AccelZ.AccelZ"\\n[factors]\\ngx = 2.0\\n')
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = Path(d) / "map.toml"
    ...     _ = path.write_text(toml)
    ...     smap = load_signal_map(path)
    >>> smap.roles["gx"]
    SignalRef(message='IMU_GyroXY', signal='GyroX', factor=2.0)
    >>> sorted(smap.roles)
    ['ax', 'ay', 'az', 'gx', 'gy', 'gz']
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"no such signal map: {path}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MapError(f"{path}: not a TOML signal map ({exc})") from None
    if doc.get("schema") != SCHEMA or doc.get("version") != 1:
        raise MapError(f"{path}: expected schema = \"{SCHEMA}\" and version = 1")
    dbc = doc.get("dbc")
    if not isinstance(dbc, str):
        raise MapError(f"{path}: dbc: missing (the DBC file, relative to the map)")
    dbc_path = (path.parent / dbc).resolve()
    try:
        db = cantools.database.load_file(str(dbc_path), database_format="dbc")
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: dbc: no such file {dbc_path}") from None
    except (cantools.database.UnsupportedDatabaseFormatError, ValueError) as exc:
        raise MapError(f"{path}: dbc: cannot load {dbc_path}: {exc}") from None
    known = {"schema", "version", "dbc", "channels", "factors", "sequence", "timestamp"}
    extra = sorted(set(doc) - known)
    if extra:
        raise MapError(f"{path}: unknown key {extra[0]!r}")
    chans = doc.get("channels", {})
    factors = doc.get("factors", {})
    bad = sorted((set(chans) | set(factors)) - set(CHANNEL_ROLES))
    if bad:
        raise MapError(f"{path}: unknown channel {bad[0]!r} (use {', '.join(CHANNEL_ROLES)})")

    def ref(key: str, text: object, factor: object = 1.0) -> SignalRef:
        if not isinstance(text, str) or text.count(".") != 1:
            raise MapError(f"{path}: {key}: expected \"MESSAGE.SIGNAL\", got {text!r}")
        if not isinstance(factor, int | float) or isinstance(factor, bool):
            raise MapError(f"{path}: factors.{key}: expected a number")
        msg, sig = text.split(".")
        return SignalRef(msg, sig, float(factor))

    roles = {r: ref(f"channels.{r}", chans.get(r), factors.get(r, 1.0)) for r in CHANNEL_ROLES
             if r in chans}
    if "sequence" in doc:
        roles["seq"] = ref("sequence.signal", doc["sequence"].get("signal"))
    if "timestamp" in doc:
        unit = doc["timestamp"].get("unit", "us")
        if unit not in TIME_UNITS:
            raise MapError(f"{path}: timestamp.unit: expected one of {', '.join(TIME_UNITS)}")
        roles["time"] = ref("timestamp.signal", doc["timestamp"].get("signal"),
                            TIME_UNITS[unit])
    if not isinstance(db, cantools.database.can.Database):
        raise MapError(f"{path}: dbc: {dbc_path} is not a CAN database")
    return SignalMap(db, roles, str(path))


# --- the decode table for C++ -------------------------------------------------------------


def decode_table(smap: SignalMap) -> list[dict[str, Any]]:
    """One entry per role: everything the C++ decoder needs, taken from cantools' parse of
    the DBC (bit position in DBC numbering, byte order, value type, scale, offset, the
    multiplexer selector's field and value).

    Examples
    --------
    The decode table of the project's DBC mapped as a user's (one row per role):

    >>> from gyrodrift.codecs.can_frames import load_dbc
    >>> names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
    ...              ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ")
    >>> smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    >>> row = decode_table(smap)[2]
    >>> row["role"], hex(row["id"]), row["start"], row["length"], row["type"]
    ('gz', '0x101', 0, 32, 'f32')
    """
    rows = []
    for role in ROLES:
        ref = smap.roles.get(role)
        if ref is None:
            continue
        msg = smap.db.get_message_by_name(ref.message)
        sig = msg.get_signal_by_name(ref.signal)
        if sig.is_float:
            vtype = {32: "f32", 64: "f64"}.get(sig.length)
            if vtype is None:
                raise MapError(f"{smap.source}: {role}: float signal of {sig.length} bits")
        else:
            vtype = "s" if sig.is_signed else "u"
        mux = None
        if sig.multiplexer_signal is not None and sig.multiplexer_ids:
            ms = msg.get_signal_by_name(sig.multiplexer_signal)
            mux = {"start": ms.start, "length": ms.length,
                   "order": "le" if ms.byte_order == "little_endian" else "be",
                   "value": int(sig.multiplexer_ids[0])}
        rows.append({
            "role": role, "id": int(msg.frame_id), "extended": bool(msg.is_extended_frame),
            "dlc": int(msg.length), "start": int(sig.start), "length": int(sig.length),
            "order": "le" if sig.byte_order == "little_endian" else "be", "type": vtype,
            "scale": float(sig.scale), "offset": float(sig.offset), "factor": ref.factor,
            "mux": mux, "message": msg.name, "signal": sig.name,
        })
    return rows


def _multiplexed_messages(smap: SignalMap) -> list[dict[str, Any]]:
    """Each mapped message that has a multiplexer: its selector's field and the values the
    DBC defines (a frame with another value decodes nothing, as in cantools)."""
    out = []
    for m in sorted(smap.messages.values(), key=lambda m: (m.frame_id, m.is_extended_frame)):
        muxes = [s for s in m.signals if s.is_multiplexer and s.multiplexer_signal is None]
        if not muxes:
            continue
        ms = muxes[0]
        values = sorted({int(v) for s in m.signals if s.multiplexer_signal == ms.name
                         for v in (s.multiplexer_ids or ())})
        if len(values) > MAX_PAGES:
            raise MapError(f"{smap.source}: {m.name}: {len(values)} multiplexer pages; the decode "
                           f"table holds at most {MAX_PAGES}")
        out.append({"id": int(m.frame_id), "extended": bool(m.is_extended_frame),
                    "dlc": int(m.length), "start": int(ms.start), "length": int(ms.length),
                    "order": "le" if ms.byte_order == "little_endian" else "be",
                    "values": values, "message": m.name})
    return out


def decode_table_text(smap: SignalMap) -> str:
    """The decode table as the text file `gyrodrift-loop --can-signals FILE` reads (and
    codecs/can_signal_decode.hpp's parse_signal_line parses): one entry per line,

        ROLE ID EXT DLC START LENGTH ORDER TYPE SCALE OFFSET FACTOR MUX

    ID hex, EXT 0/1, ORDER le|be, TYPE u|s|f32|f64, numbers in repr() form (they round-trip
    exactly through strtod), MUX '-' or START:LENGTH:ORDER:VALUE. '#' starts a comment. Each
    mapped message with a multiplexer also gets ``pages ID EXT DLC START:LENGTH:ORDER
    V1,V2,...``: the values its DBC defines (a frame with another value decodes nothing).

    Examples
    --------
    The table line of the gx channel, as gyrodrift-loop reads it:

    >>> from gyrodrift.codecs.can_frames import load_dbc
    >>> names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
    ...              ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ")
    >>> smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    >>> print(decode_table_text(smap).splitlines()[3])
    gx 0x100 0 8 0 32 le f32 1.0 0.0 1.0 -  # IMU_GyroXY.GyroX
    """
    lines = [TABLE_HEADER,
             f"# generated from {Path(smap.source).name or 'a signal map'} by "
             "gyrodrift.codecs.can_signals.decode_table_text",
             "# role id ext dlc start length order type scale offset factor mux"]
    for m in _multiplexed_messages(smap):
        values = ",".join(str(v) for v in m["values"])
        lines.append(f"pages {m['id']:#x} {int(m['extended'])} {m['dlc']} "
                     f"{m['start']}:{m['length']}:{m['order']}:{values}  # {m['message']}")
    for e in decode_table(smap):
        mux = "-" if e["mux"] is None else \
            f"{e['mux']['start']}:{e['mux']['length']}:{e['mux']['order']}:{e['mux']['value']}"
        lines.append(f"{e['role']} {e['id']:#x} {int(e['extended'])} {e['dlc']} {e['start']} "
                     f"{e['length']} {e['order']} {e['type']} {e['scale']!r} {e['offset']!r} "
                     f"{e['factor']!r} {mux}  # {e['message']}.{e['signal']}")
    return "\n".join(lines) + "\n"


# --- encoding (what a vendor IMU would send; the replay harness uses it) ------------------


def encode_sample_frames(smap: SignalMap, seq: int, t_us: int,
                         values: Any) -> list[can.Message]:
    """One sample as the frames of the user's DBC, encoded by cantools: each mapped message
    (each multiplexer page) once, the mapped signals set from the channel values (divided by
    their factor), the counter as seq modulo its width, the timestamp from t_us; every other
    signal of the message or page is 0. Integer signals are rounded and clipped to their
    width (a value the DBC cannot carry is clipped, as the IMU would saturate).

    Examples
    --------
    One sample encoded as the frames of the mapped messages:

    >>> from gyrodrift.codecs.can_frames import load_dbc
    >>> names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
    ...              ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ")
    >>> smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    >>> [hex(m.arbitration_id) for m in encode_sample_frames(smap, 3, 0, [0.5] * 6)]
    ['0x100', '0x101', '0x102', '0x103']
    """
    vals = [float(v) for v in values]
    if len(vals) != len(CHANNEL_ROLES):
        raise MapError(f"values: expected 6 channels, got {len(vals)}")
    groups: dict[tuple[str, int | None], dict[str, Any]] = {}
    for role, ref in smap.roles.items():
        msg = smap.db.get_message_by_name(ref.message)
        sig = msg.get_signal_by_name(ref.signal)
        page = None if sig.multiplexer_ids is None else int(sig.multiplexer_ids[0])
        if role == "seq":
            raw: float | int = int(seq) % (1 << sig.length)
        else:
            phys = (float(t_us) if role == "time" else vals[CHANNEL_ROLES.index(role)]) \
                / ref.factor
            raw = _to_raw(sig, phys)
        groups.setdefault((ref.message, page), {})[ref.signal] = raw
    out = []
    for (name, page), mapped in groups.items():
        msg = smap.db.get_message_by_name(name)
        raw_all: dict[str, Any] = {}
        for sig in msg.signals:
            if sig.multiplexer_ids is not None and page not in sig.multiplexer_ids:
                continue
            raw_all[sig.name] = mapped.get(sig.name, 0.0 if sig.is_float else 0)
            if sig.is_multiplexer and page is not None:
                raw_all[sig.name] = page
        data = msg.encode(raw_all, scaling=False, strict=False)
        out.append(can.Message(arbitration_id=msg.frame_id, data=data,
                               is_extended_id=bool(msg.is_extended_frame)))
    return out


def _to_raw(sig: Any, phys: float) -> float | int:
    scaled = (phys - float(sig.offset)) / float(sig.scale)
    if sig.is_float:
        return scaled
    lo, hi = (-(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1) if sig.is_signed \
        else (0, (1 << sig.length) - 1)
    if not math.isfinite(scaled):
        return hi if scaled > 0 else (lo if scaled < 0 else 0)
    return int(min(max(round(scaled), lo), hi))


# --- assembly (the Python twin of SignalSampleAssembler in codecs/can_signal_decode.hpp) ----------


@dataclass
class SignalSample:
    """One sample decoded through a signal map: sequence, the IMU's timestamp (us) if
    mapped, six values.

    Examples
    --------
    >>> SignalSample(seq=3, t_us=None, values=(0.0,) * 6).t_us is None
    True
    """
    seq: int  # 16-bit sequence (the unwrapped counter, or a running count without one)
    t_us: int | None  # the IMU's own time when mapped
    values: tuple[float, ...]  # gx gy gz (rad/s), ax ay az (m/s^2), as float (float64)


@dataclass
class SignalRxStats:
    """The receive counters of a :class:`SignalSampleAssembler` (the module docstring's accounting).

    Examples
    --------
    >>> SignalRxStats().frames_in
    0
    """
    frames_in: int = 0
    frames_used: int = 0
    frames_dropped: int = 0
    foreign_frames: int = 0
    ignored_frames: int = 0
    undefined_page_frames: int = 0
    bad_dlc: int = 0
    complete_samples: int = 0
    incomplete_samples: int = 0


@dataclass
class SignalSampleAssembler:
    """Samples from frames decoded with cantools by a user's DBC (rules: module docstring).

    Examples
    --------
    Frames encoded through a map, reassembled through the same map:

    >>> from gyrodrift.codecs.can_frames import load_dbc
    >>> names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
    ...              ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ",
    ...              seq="IMU_GyroZ.Seq")
    >>> smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    >>> asm = SignalSampleAssembler(smap)
    >>> out = [asm.push(m) for m in encode_sample_frames(smap, 3, 0, [0.5, 0.25, 0, 0, 0, 9.75])]
    >>> out[-1]
    SignalSample(seq=3, t_us=None, values=(0.5, 0.25, 0.0, 0.0, 0.0, 9.75))
    >>> asm.stats.complete_samples, asm.stats.frames_used
    (1, 4)
    """

    smap: SignalMap
    stats: SignalRxStats = field(default_factory=SignalRxStats)
    _filled: dict[str, float] = field(default_factory=dict)
    _held: int = 0
    _seq16: int = 0
    _last_counter: int | None = None
    _count: int = 0

    def __post_init__(self) -> None:
        self._messages = self.smap.messages
        self._needed = set(self.smap.roles)
        self._by_message: dict[str, list[tuple[str, SignalRef]]] = {}
        for role, ref in self.smap.roles.items():
            self._by_message.setdefault(ref.message, []).append((role, ref))

    @property
    def pending_frames(self) -> int:
        return self._held

    def is_mapped(self, msg: can.Message) -> bool:
        return (msg.arbitration_id, bool(msg.is_extended_id)) in self._messages

    def push(self, msg: can.Message) -> SignalSample | None:
        st = self.stats
        st.frames_in += 1
        m = self._messages.get((msg.arbitration_id, bool(msg.is_extended_id)))
        if m is None or msg.is_remote_frame or msg.is_error_frame:
            st.foreign_frames += 1
            return None
        data = bytes(msg.data)
        if len(data) < m.length:
            st.bad_dlc += 1
            st.frames_dropped += 1
            return None
        try:
            sig = m.decode(data, decode_choices=False, scaling=True)
        except cantools.database.DecodeError:
            # a multiplexer value the DBC does not define: cantools decodes nothing of it
            st.ignored_frames += 1
            st.undefined_page_frames += 1
            return None
        got = {role: float(sig[ref.signal]) * ref.factor
               for role, ref in self._by_message[m.name] if ref.signal in sig}
        if not got:
            st.ignored_frames += 1
            return None
        if any(r in self._filled for r in got):
            self._drop()
        self._filled.update(got)
        self._held += 1
        if not self._needed.issubset(self._filled):
            return None
        out = self._emit()
        st.frames_used += self._held
        st.complete_samples += 1
        self._filled = {}
        self._held = 0
        return out

    def _emit(self) -> SignalSample:
        f = self._filled
        if "seq" in f:
            counter = int(f["seq"])
            if self._last_counter is None:
                self._seq16 = counter & 0xFFFF
            else:
                step = (counter - self._last_counter) % (1 << self.smap.seq_bits)
                self._seq16 = (self._seq16 + step) & 0xFFFF
            self._last_counter = counter
            seq = self._seq16
        else:
            seq = self._count & 0xFFFF
        self._count += 1
        t_us = None
        if "time" in f:
            t = f["time"]
            t_us = math.floor(t + 0.5) if math.isfinite(t) and t >= 0 else 0
        return SignalSample(seq, t_us, tuple(f[r] for r in CHANNEL_ROLES))

    def _drop(self) -> None:
        if self._held:
            self.stats.incomplete_samples += 1
            self.stats.frames_dropped += self._held
        self._filled = {}
        self._held = 0

    def finish(self) -> None:
        """End of stream: a partial sample is counted as incomplete."""
        self._drop()
