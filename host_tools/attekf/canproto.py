"""The node's CAN protocol on the host side, from the same DBC as the C code.

``firmware/app/dbc/attekf.dbc`` is the single source of truth of the wire format
(docs/can_protocol.md).
This module

* loads it with cantools (:func:`database`);
* encodes IMU samples into the input frames (IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC) the way the
  node expects them: :func:`encode_samples` (vectorised over a whole recording; the bit layout and
  scalings are read from the DBC, and a test checks it gives the bytes of cantools'
  ``encode_message``), with values clamped to the signal ranges and the saturation flagged;
* decodes the estimator's output frames back into rows (:class:`OutputDecoder`) and the input
  frames back into samples (:class:`InputDecoder`), with cantools' ``decode_message``;
* generates the C pack/unpack code (``cantools generate_c_source``) and the tables of
  docs/can_protocol.md, and checks that the committed ones are current::

      python -m attekf.canproto generate     # rewrite firmware/app/dbc/canmsg_gen.[ch] and the doc tables
      python -m attekf.canproto check        # exit 1 if either is stale
"""

from __future__ import annotations

import argparse
import functools
import os
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

# ---------------------------------------------------------------------------------------------
# Where the DBC is
# ---------------------------------------------------------------------------------------------
REPO_ROOT = Path(__file__).resolve().parents[2]
DBC_RELPATH = Path("firmware/app/dbc/attekf.dbc")
C_DATABASE_NAME = "canmsg"            # prefix canmsg_ of the generated names
C_FILE_STEM = C_DATABASE_NAME + "_gen"  # -> firmware/app/dbc/canmsg_gen.c, .h (generated code: *_gen)
C_OPTIONS = ("--use-float", "--use-round")  # float-only target, rounding like Python's encoder
DOC_RELPATH = Path("docs/can_protocol.md")
DOC_BEGIN = "<!-- BEGIN GENERATED FROM firmware/app/dbc/attekf.dbc (python -m attekf.canproto generate) -->"
# The C headers whose bit definitions the DBC's status signals and value tables must match.
ATT_H = Path("firmware/att/att.h")
APP_MSG_H = Path("firmware/app/app_msg.h")
DOC_END = "<!-- END GENERATED -->"

# Sensor bits (hal/include/hal.h HAL_HAS_*)
HAS_GYRO, HAS_ACCEL, HAS_MAG = 1, 2, 4

# app_counter_id_t order (firmware/app/app_msg.h); the ATT_COUNTERS pages use these indices
# (`check` compares them with the DBC's value table of Page).
COUNTER_NAMES = (
    "rx_frames", "foreign", "bad_dlc", "duplicate", "late", "incomplete", "discarded",
    "rx_overflow", "link_down", "tx_frames", "tx_errors", "samples", "gaps", "missing",
    "stale", "time_errors", "resync", "saturated", "ekf_rejected", "realign", "outputs",
    "transfer_errors", "requests", "refused",
)

# ATT_STATUS bit signals -> APP_FLAG_* bit values of firmware/app/app_msg.h (`check` compares
# them with the header and with the signals' positions in the DBC)
STATUS_BITS = {
    "Aligned": 1 << 0, "Stale": 1 << 1, "Gap": 1 << 2, "InSaturated": 1 << 3,
    "OutSaturated": 1 << 4, "LinkError": 1 << 5, "FrameError": 1 << 6, "Incomplete": 1 << 7,
    "EkfReject": 1 << 8, "TimeError": 1 << 9, "Restarted": 1 << 10, "Heartbeat": 1 << 11,
    "ConfigPending": 1 << 12,
}


class ProtocolError(Exception):
    """The DBC cannot be found or does not have the layout this module relies on."""


def dbc_path() -> Path:
    """The DBC: $ATTEKF_DBC if set, else the installed package's copy (attekf/data/), else
    firmware/app/dbc/attekf.dbc of this source tree."""
    env = os.environ.get("ATTEKF_DBC")
    packaged = Path(__file__).resolve().parent / "data" / "attekf.dbc"
    p = Path(env) if env else packaged if packaged.is_file() else REPO_ROOT / DBC_RELPATH
    if not p.is_file():
        raise ProtocolError(f"{p}: CAN database not found (the package's attekf/data/attekf.dbc is "
                            "missing: reinstall attekf, or set ATTEKF_DBC to a copy of the database)")
    return p


@functools.lru_cache(maxsize=None)
def database():
    """The cantools database of the protocol (cached)."""
    import cantools
    return cantools.database.load_file(str(dbc_path()))


@functools.lru_cache(maxsize=None)
def frame_id(name: str) -> int:
    return database().get_message_by_name(name).frame_id


def ids() -> Dict[str, int]:
    """Frame id of every message, by name."""
    return {m.name: m.frame_id for m in database().messages}


INPUT_MESSAGES = ("IMU_GYRO", "IMU_ACCEL", "IMU_MAG", "IMU_SYNC")
OUTPUT_MESSAGES = ("ATT_EULER", "ATT_RATES", "ATT_SIGMA", "ATT_STATUS", "ATT_COUNTERS")
SENSOR_MESSAGES = (("IMU_GYRO", ("GyroX", "GyroY", "GyroZ"), HAS_GYRO),
                   ("IMU_ACCEL", ("AccelX", "AccelY", "AccelZ"), HAS_ACCEL),
                   ("IMU_MAG", ("MagX", "MagY", "MagZ"), HAS_MAG))


def signal_range(message: str, signal: str) -> Tuple[float, float]:
    """Physical [min, max] of a signal, from the DBC."""
    s = database().get_message_by_name(message).get_signal_by_name(signal)
    return float(s.minimum), float(s.maximum)


def resolution(message: str, signal: str) -> float:
    """Physical value of one LSB of a signal, from the DBC."""
    return float(database().get_message_by_name(message).get_signal_by_name(signal).scale)


# ---------------------------------------------------------------------------------------------
# Vectorised encoding (layout from the DBC)
# ---------------------------------------------------------------------------------------------
def encode_message_vec(name: str, values: Dict[str, np.ndarray]) -> np.ndarray:
    """Encodes n messages at once: values[signal] are (n,) physical values (already inside the
    signal's range; missing signals are 0). Returns (n, 8) uint8 payloads, byte-identical to
    cantools' encode_message (raw = round-half-even((v - offset) / scale), little-endian).
    Only little-endian, non-multiplexed messages (the IMU_* ones)."""
    msg = database().get_message_by_name(name)
    if msg.is_multiplexed():
        raise ProtocolError(f"{name}: multiplexed, use cantools' encode_message")
    n = None
    word = None
    for sig in msg.signals:
        if sig.byte_order != "little_endian":
            raise ProtocolError(f"{name}.{sig.name}: big-endian signals are not supported here")
        v = values.get(sig.name)
        if v is None:
            continue
        v = np.asarray(v, dtype=np.float64)
        if n is None:
            n = v.shape[0]
            word = np.zeros(n, dtype=np.uint64)
        raw = np.round((v - float(sig.offset)) / float(sig.scale)).astype(np.int64)
        lo = -(1 << (sig.length - 1)) if sig.is_signed else 0
        hi = (1 << (sig.length - 1)) - 1 if sig.is_signed else (1 << sig.length) - 1
        if np.any(raw < lo) or np.any(raw > hi):
            raise ProtocolError(f"{name}.{sig.name}: value outside the signal's integer range")
        mask = (1 << sig.length) - 1
        bits = (raw & mask).astype(np.uint64)
        word |= bits << np.uint64(sig.start)
    if word is None:
        raise ProtocolError(f"{name}: no signal values given")
    return word.astype("<u8").view(np.uint8).reshape(n, 8)


@dataclass
class EncodedFrames:
    """Input frames of a block of samples, in sending order.

    t        (M,) s, the sample time of the frame's sample
    ids      (M,) frame ids
    data     (M, 8) uint8 payloads
    sample   (M,) index of the sample (0-based within the block)
    saturated  per sensor name, how many samples had a value clamped to the wire range
    """
    t: np.ndarray
    ids: np.ndarray
    data: np.ndarray
    sample: np.ndarray
    saturated: Dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.ids.shape[0])


def time_us(t_s: np.ndarray) -> np.ndarray:
    """Sample times on the wire: microseconds, rounded (IMU_SYNC.TimeUs before the 2^32 wrap)."""
    t_s = np.asarray(t_s, dtype=np.float64)
    if t_s.size and (not np.all(np.isfinite(t_s)) or t_s.min() < 0):
        raise ProtocolError("sample times must be finite and >= 0 s")
    return np.round(t_s * 1e6).astype(np.int64)


def encode_samples(t_s: np.ndarray, gyr: np.ndarray, acc: Optional[np.ndarray] = None,
                   mag: Optional[np.ndarray] = None, seq0: int = 0) -> EncodedFrames:
    """The input frames of samples t_s (s, >= 0), gyr (rad/s), acc (m/s^2), mag (uT), each (n, 3)
    or None. A sensor row with a NaN is not sent for that sample (its Has* bit is 0). Values
    outside a signal's range are clamped to it and the sample's Sat* bit is set. Sequence numbers
    are seq0 + i modulo 65536; TimeUs is round(t * 1e6) modulo 2^32. Per sample: the sensor frames
    present, then IMU_SYNC."""
    t_s = np.asarray(t_s, dtype=np.float64)
    n = t_s.shape[0]
    seq = (seq0 + np.arange(n, dtype=np.int64)) & 0xFFFF
    tus = time_us(t_s) & 0xFFFFFFFF
    sensors = (gyr, acc, mag)
    present = []
    sync = {"TimeUs": tus.astype(np.float64), "Seq": seq.astype(np.float64)}
    saturated = {}
    payloads = []
    for (name, sigs, bit), arr in zip(SENSOR_MESSAGES, sensors):
        key = name.split("_")[1].lower()
        has = np.zeros(n, dtype=bool) if arr is None else np.all(np.isfinite(np.asarray(arr, float)), axis=1)
        sat = np.zeros(n, dtype=bool)
        data = None
        if arr is not None and has.any():
            a = np.where(has[:, None], np.asarray(arr, dtype=np.float64), 0.0)
            vals = {"Seq": seq.astype(np.float64)}
            for j, sname in enumerate(sigs):
                lo, hi = signal_range(name, sname)
                sat |= (a[:, j] < lo) | (a[:, j] > hi)
                vals[sname] = np.clip(a[:, j], lo, hi)
            data = encode_message_vec(name, vals)
        sat &= has
        saturated[key] = int(sat.sum())
        present.append(has)
        payloads.append(data)
        flag = {"gyro": "Gyro", "accel": "Accel", "mag": "Mag"}[key]
        sync["Has" + flag] = has.astype(np.float64)
        sync["Sat" + flag] = sat.astype(np.float64)
    sync_data = encode_message_vec("IMU_SYNC", sync)

    # Interleave: per sample, the present sensor frames then IMU_SYNC.
    counts = 1 + sum(p.astype(np.int64) for p in present)
    start = np.concatenate(([0], np.cumsum(counts)[:-1]))
    m = int(counts.sum())
    out_ids = np.zeros(m, dtype=np.uint32)
    out_data = np.zeros((m, 8), dtype=np.uint8)
    out_sample = np.zeros(m, dtype=np.int64)
    offset = np.zeros(n, dtype=np.int64)
    for (name, _sigs, _bit), has, data in zip(SENSOR_MESSAGES, present, payloads):
        idx = np.nonzero(has)[0]
        pos = start[idx] + offset[idx]
        out_ids[pos] = frame_id(name)
        out_data[pos] = data[idx]
        out_sample[pos] = idx
        offset[idx] += 1
    pos = start + offset
    out_ids[pos] = frame_id("IMU_SYNC")
    out_data[pos] = sync_data
    out_sample[pos] = np.arange(n)
    return EncodedFrames(t=t_s[out_sample], ids=out_ids, data=out_data, sample=out_sample,
                         saturated=saturated)


# ---------------------------------------------------------------------------------------------
# Decoding
# ---------------------------------------------------------------------------------------------
def status_flags(decoded: Dict[str, object]) -> int:
    """APP_FLAG_* word (firmware/app/app_msg.h) from a decoded ATT_STATUS."""
    return sum(bit for name, bit in STATUS_BITS.items() if int(decoded[name]))


@dataclass
class OutputRow:
    """One attitude output of the node (ATT_EULER + ATT_RATES + ATT_SIGMA + ATT_STATUS)."""
    rx_time: float                 # bus timestamp of its ATT_EULER frame, s
    seq: int                       # input sample the estimate includes
    index: int                     # ATT_STATUS.OutIndex
    euler: Tuple[float, float, float]
    rates: Tuple[float, float, float]
    sigma: Tuple[float, float, float]
    flags: int                     # APP_FLAG_*
    att_flags: int                 # ATT_FLAG_*


class OutputDecoder:
    """Turns the node's output frames into rows (feed frames in bus order).

    An attitude output is ATT_EULER, ATT_RATES, ATT_SIGMA and ATT_STATUS with the same Seq; a
    status with Heartbeat set is a heartbeat. ATT_COUNTERS pages update ``counters``. Frames of
    other ids are ignored; outputs whose frames do not match up are counted in ``broken``."""

    def __init__(self) -> None:
        self.db = database()
        self.ids = {frame_id(n): n for n in OUTPUT_MESSAGES}
        self.rows: List[OutputRow] = []
        self.heartbeats: List[Tuple[float, int, int]] = []  # (rx_time, flags, index)
        self.counters: Dict[str, int] = {}
        self.broken = 0
        self.frames = 0
        self._part: Dict[str, Tuple[float, Dict[str, object]]] = {}

    def feed(self, timestamp: float, arbitration_id: int, data: bytes) -> None:
        name = self.ids.get(arbitration_id)
        if name is None or len(data) != 8:
            return
        self.frames += 1
        d = self.db.decode_message(arbitration_id, bytes(data), decode_choices=False)
        if name == "ATT_COUNTERS":
            page = int(d["Page"])
            if 0 <= page < len(COUNTER_NAMES):
                value = [v for k, v in d.items() if k != "Page"]
                if value:
                    self.counters[COUNTER_NAMES[page]] = int(value[0])
            return
        if name != "ATT_STATUS":
            self._part[name] = (timestamp, d)
            return
        flags = status_flags(d)
        if flags & STATUS_BITS["Heartbeat"]:
            self.heartbeats.append((timestamp, flags, int(d["OutIndex"])))
            return
        seq = int(d["Seq"])
        parts = [self._part.get(n) for n in ("ATT_EULER", "ATT_RATES", "ATT_SIGMA")]
        self._part = {}
        if any(p is None or int(p[1]["Seq"]) != seq for p in parts):
            self.broken += 1
            return
        e, r, s = (p[1] for p in parts)
        self.rows.append(OutputRow(
            rx_time=parts[0][0], seq=seq, index=int(d["OutIndex"]),
            euler=(float(e["Roll"]), float(e["Pitch"]), float(e["Yaw"])),
            rates=(float(r["RateP"]), float(r["RateQ"]), float(r["RateR"])),
            sigma=(float(s["SigmaRoll"]), float(s["SigmaPitch"]), float(s["SigmaYaw"])),
            flags=flags, att_flags=int(d["AttFlags"])))


@dataclass
class InputSample:
    rx_time: float                  # bus timestamp of its IMU_SYNC, s
    seq: int
    time_us: int                    # IMU_SYNC.TimeUs (modulo 2^32)
    gyro: Optional[Tuple[float, float, float]]
    accel: Optional[Tuple[float, float, float]]
    mag: Optional[Tuple[float, float, float]]
    saturated: int                  # HAS_* bits


class InputDecoder:
    """Turns IMU input frames back into samples (a sample ends with its IMU_SYNC). For recording
    and checking what was on the bus, not the node's robust assembly (firmware/app/dbc/dbc_rx.c)."""

    def __init__(self) -> None:
        self.db = database()
        self.ids = {frame_id(n): n for n in INPUT_MESSAGES}
        self.samples: List[InputSample] = []
        self.frames = 0
        self._pending: Dict[int, Dict[str, Tuple[float, float, float]]] = {}

    def feed(self, timestamp: float, arbitration_id: int, data: bytes) -> Optional[InputSample]:
        name = self.ids.get(arbitration_id)
        if name is None or len(data) != 8:
            return None
        self.frames += 1
        d = self.db.decode_message(arbitration_id, bytes(data), decode_choices=False)
        seq = int(d["Seq"])
        if name != "IMU_SYNC":
            sigs = dict((m, s) for m, s, _b in SENSOR_MESSAGES)[name]
            self._pending.setdefault(seq, {})[name] = tuple(float(d[s]) for s in sigs)
            if len(self._pending) > 16:  # frames of samples whose IMU_SYNC never came
                self._pending.pop(next(iter(self._pending)))
            return None
        got = self._pending.pop(seq, {})
        sat = ((HAS_GYRO if d["SatGyro"] else 0) | (HAS_ACCEL if d["SatAccel"] else 0)
               | (HAS_MAG if d["SatMag"] else 0))
        s = InputSample(rx_time=timestamp, seq=seq, time_us=int(d["TimeUs"]),
                        gyro=got.get("IMU_GYRO") if d["HasGyro"] else None,
                        accel=got.get("IMU_ACCEL") if d["HasAccel"] else None,
                        mag=got.get("IMU_MAG") if d["HasMag"] else None, saturated=sat)
        self.samples.append(s)
        return s


def unwrap_time_us(raw: Sequence[int]) -> np.ndarray:
    """IMU_SYNC.TimeUs values (modulo 2^32) back to a monotonic microsecond count, the way the
    node unwraps them (signed 32-bit differences)."""
    raw = np.asarray(raw, dtype=np.int64)
    if raw.size == 0:
        return raw
    d = np.diff(raw) & 0xFFFFFFFF
    d = np.where(d >= 1 << 31, d - (1 << 32), d)
    return raw[0] + np.concatenate(([0], np.cumsum(d)))


def output_schedule(t_us: Sequence[int], period_us: int) -> np.ndarray:
    """Indices of the samples after which the node publishes an attitude output, for an
    uninterrupted stream with sample times t_us (firmware/app/app.c: the first sample, then each
    sample whose time reaches the next multiple of the period after it)."""
    t_us = np.asarray(t_us, dtype=np.int64)
    if period_us <= 0:
        return np.arange(t_us.size)
    out = []
    nxt = None
    for i, t in enumerate(t_us.tolist()):
        if nxt is None or t >= nxt:
            if nxt is None:
                nxt = t
            k = (t - nxt) // period_us + 1
            nxt += k * period_us
            out.append(i)
    return np.asarray(out, dtype=np.int64)


# ---------------------------------------------------------------------------------------------
# C code and documentation generated from the DBC
# ---------------------------------------------------------------------------------------------
_STAMP = re.compile(r"(generated by cantools version \S+)[^\n]*")


def generate_c() -> Dict[str, str]:
    """canmsg_gen.h / canmsg_gen.c as ``cantools generate_c_source --use-float --use-round
    --database-name canmsg`` writes them (under those file names), with the generation date
    removed from the header comment (so that the committed files are reproducible). Returns
    {file name: text}."""
    from cantools.database.can.c_source import generate
    h, c, _fz, _mk = generate(database(), C_DATABASE_NAME, C_FILE_STEM + ".h",
                              C_FILE_STEM + ".c", C_FILE_STEM + "_fuzzer.c",
                              floating_point_numbers=True, bit_fields=False, use_float=True,
                              node_name=None, use_round=True)

    def fix(text: str) -> str:
        return _STAMP.sub(r"\1 from firmware/app/dbc/attekf.dbc (python -m attekf.canproto generate).", text, count=1)
    return {C_FILE_STEM + ".h": fix(h), C_FILE_STEM + ".c": fix(c)}


def _fmt_num(v) -> str:
    if v is None:
        return ""
    v = float(v)
    return f"{int(v)}" if v == int(v) and abs(v) < 1e12 else f"{v:g}"


def doc_tables() -> str:
    """Markdown tables of every frame and signal, from the DBC."""
    db = database()
    lines = [DOC_BEGIN, ""]
    lines += ["| Id | Frame | Sender | Length | Description |", "|---|---|---|---|---|"]
    for m in db.messages:
        lines.append(f"| 0x{m.frame_id:03X} | {m.name} | {', '.join(m.senders)} | {m.length} | "
                     f"{(m.comment or '').strip()} |")
    for m in db.messages:
        lines += ["", f"### {m.name} (0x{m.frame_id:03X})", ""]
        lines += ["| Signal | Bits | Type | Resolution | Min | Max | Unit | Description |",
                  "|---|---|---|---|---|---|---|---|"]
        for s in m.signals:
            kind = ("int" if s.is_signed else "uint") + str(s.length)
            mux = ""
            if s.is_multiplexer:
                mux = " (multiplexer)"
            elif s.multiplexer_ids:
                mux = f" (Page {','.join(str(i) for i in s.multiplexer_ids)})"
            lines.append(f"| {s.name}{mux} | {s.start}..{s.start + s.length - 1} | {kind} | "
                         f"{_fmt_num(s.scale)} | {_fmt_num(s.minimum)} | {_fmt_num(s.maximum)} | "
                         f"{s.unit or ''} | {(s.comment or '').strip()} |")
    lines += ["", DOC_END]
    return "\n".join(lines)


def _doc_with_tables(text: str) -> str:
    a, b = text.find(DOC_BEGIN), text.find(DOC_END)
    if a < 0 or b < a:
        raise ProtocolError(f"{DOC_RELPATH}: markers for the generated tables not found")
    return text[:a] + doc_tables() + text[b + len(DOC_END):]


def _camel(upper: str) -> str:
    """FRAME_ERROR -> FrameError."""
    return "".join(w.capitalize() for w in upper.split("_"))


def header_mismatches(root: Path) -> List[str]:
    """Where the DBC disagrees with the C headers that define the same bits: ATT_STATUS's bit
    signals with APP_FLAG_* (firmware/app/app_msg.h) and STATUS_BITS, AttFlags' value table with
    ATT_FLAG_* (firmware/att/att.h), the ATT_COUNTERS pages with APP_COUNTERS (app_msg.h) and
    COUNTER_NAMES. One line per disagreement."""
    out: List[str] = []
    db = database()
    status = db.get_message_by_name("ATT_STATUS")
    app_h = (root / APP_MSG_H).read_text(encoding="utf-8")
    app_flags = {_camel(n): 1 << int(b) for n, b in
                 re.findall(r"#define APP_FLAG_(\w+)\s+\(1u << (\d+)\)", app_h)}
    dbc_bits = {sg.name: 1 << sg.start for sg in status.signals if sg.length == 1}
    if app_flags != dbc_bits:
        out.append(f"{APP_MSG_H} APP_FLAG_* {app_flags} != ATT_STATUS bit signals {dbc_bits}")
    if STATUS_BITS != dbc_bits:
        out.append(f"canproto.STATUS_BITS != ATT_STATUS bit signals {dbc_bits}")
    att_h = (root / ATT_H).read_text(encoding="utf-8")
    att_flags = {1 << int(b): n for n, b in re.findall(r"#define ATT_FLAG_(\w+)\s+\(1u << (\d+)\)", att_h)}
    table = {int(k): str(v) for k, v in status.get_signal_by_name("AttFlags").choices.items()}
    if att_flags != table:
        out.append(f"{ATT_H} ATT_FLAG_* {att_flags} != the AttFlags value table {table}")
    counters = tuple(re.findall(r"X\(\w+, (\w+),", app_h.split("#define APP_COUNTERS(X)")[1].split("#define APP_COUNTER_ENUM")[0]))
    pages = db.get_message_by_name("ATT_COUNTERS").get_signal_by_name("Page")
    dbc_pages = tuple(str(pages.choices[k]) for k in sorted(pages.choices))
    if counters != COUNTER_NAMES or dbc_pages != COUNTER_NAMES or int(pages.maximum) != len(COUNTER_NAMES) - 1:
        out.append(f"counters: {APP_MSG_H} {counters}, the DBC's Page table {dbc_pages} (max "
                   f"{pages.maximum}) and canproto.COUNTER_NAMES differ")
    return out


def _targets(root: Path) -> Dict[Path, str]:
    out = {root / "firmware/app/dbc" / name: text for name, text in generate_c().items()}
    doc = root / DOC_RELPATH
    if doc.is_file():
        out[doc] = _doc_with_tables(doc.read_text(encoding="utf-8"))
    else:
        raise ProtocolError(f"{doc}: missing")
    return out


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m attekf.canproto",
        description="Generate (or check) the C pack/unpack code firmware/app/dbc/canmsg_gen.[ch] and the "
                    "tables of docs/can_protocol.md from firmware/app/dbc/attekf.dbc; check also compares "
                    "the DBC's status bits, flag and counter tables with the C headers.")
    ap.add_argument("action", choices=("generate", "check"),
                    help="generate: rewrite the files; check: exit 1 if any is not current")
    ap.add_argument("--root", default=str(REPO_ROOT), help="source tree (default: this one)")
    args = ap.parse_args(argv)
    try:
        targets = _targets(Path(args.root))
        drift = header_mismatches(Path(args.root))
    except (ProtocolError, OSError) as e:
        print(f"canproto: {e}", file=sys.stderr)
        return 1
    for d in drift:
        print(f"canproto: the DBC and the C headers disagree: {d}", file=sys.stderr)
    stale = [p for p, text in targets.items()
             if not p.is_file() or p.read_text(encoding="utf-8") != text]
    if args.action == "check":
        for p in stale:
            print(f"canproto: {p} is not current: run python -m attekf.canproto generate",
                  file=sys.stderr)
        return 1 if stale or drift else 0
    for p in stale:
        p.write_text(targets[p], encoding="utf-8")
        print(f"canproto: wrote {p}")
    return 1 if drift else 0


if __name__ == "__main__":
    sys.exit(main())
