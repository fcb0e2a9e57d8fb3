"""``attekf replay``: put a recorded IMU stream on a CAN bus (or into a CAN log file)."""

from __future__ import annotations

import errno
import json
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from typing import Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from . import set_signal as _set_signal, finite_float, nonneg_float, nonneg_int, positive_float
from ..canlog import LOG_EXTS, check_log_name, read_frames
from ..errors import DeviceError, InputError, Interrupted, UsageError

NAME = "replay"
HELP = "replay a recording (CSV, BROAD HDF5) or a CAN log onto a python-can interface or into a log"
DESCRIPTION = """\
Replays a recorded IMU stream as the node's input frames (the node's CAN database, attekf.dbc
in the package: IMU_GYRO, IMU_ACCEL, IMU_MAG, IMU_SYNC per sample) onto any python-can
interface, or writes them to a CAN log file.

Inputs: a recording (.csv with the columns of attekf run --help, or the BROAD .hdf5 layout),
or a CAN log python-can reads (.log candump, .asc, .blf), replayed frame by frame with its
original timing.

Recordings: sample k of the file gets Seq = k mod 65536 and TimeUs = round(t_k * 1e6) mod 2^32;
a NaN magnetometer row is a sample without magnetometer; values outside a signal's range are
clamped and flagged (Sat* bits).

Timing: paced at recorded time (--speed scales it), or --fast (as fast as the interface takes
it, optionally capped by --max-fps). Send failures (interface down, full queue) are counted and
reported; the replay goes on. Ctrl-C or SIGTERM stops sending; the summary and --stats say
how much was sent. --to-log writes the log under a temporary name and renames it when
complete: an interrupted run leaves no log.

python-can's 'virtual' interface connects only buses inside one process: frames replayed on
it from this command reach no other program (attekf record, attekf-node). Between processes
use socketcan (a vcan0 interface: ip link add vcan0 type vcan; ip link set vcan0 up).

examples:
  attekf replay rec.csv -i socketcan -c vcan0
  attekf replay trial.hdf5 -i socketcan -c can0 --start 10 --stop 40 --speed 2
  attekf replay rec.csv --to-log frames.log          (for attekf-node --replay)
  attekf replay bus.log -i socketcan -c vcan0 --fast --loop 3
"""

RECORDING_EXT = (".csv", ".hdf5", ".h5")
CANLOG_EXT = LOG_EXTS

# A bad input file is an InputError like every reader's; ReplayError names the same class
# for callers (the fuzz target) that catch replay's errors by that name.
ReplayError = InputError

VIRTUAL_WARNING = ("warning: python-can's 'virtual' interface reaches only buses in this same "
                   "process: no other program (attekf record, attekf-node) receives these frames; "
                   "between processes use -i socketcan -c vcan0")


@dataclass
class Frames:
    """Frames to send, in order: times (s, on the recording's clock), ids, payloads."""
    t: np.ndarray
    ids: np.ndarray
    data: List[bytes]
    extended: np.ndarray
    samples: int = 0
    saturated: Dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.data)


def add_arguments(p) -> None:
    p.add_argument("input", help="recording (.csv, .hdf5, .h5) or CAN log (.log, .asc, .blf)")
    out = p.add_argument_group("destination (one of)")
    out.add_argument("-i", "--interface", help="python-can interface: socketcan, virtual, ...")
    out.add_argument("-c", "--channel", help="channel of the interface (vcan0, can0, ...; needed by all but virtual)")
    out.add_argument("--bitrate", type=int, help="bitrate, for interfaces that set it")
    out.add_argument("--to-log", metavar="FILE",
                     help="write the frames to a CAN log instead (.log, .asc, .blf, ...; python-can "
                          "picks the format from the extension), time stamps = sample times")
    tm = p.add_argument_group("timing")
    tm.add_argument("--speed", type=positive_float, default=1.0,
                    help="time scale: 2 = twice as fast (default 1)")
    tm.add_argument("--fast", action="store_true", help="as fast as possible (ignore time stamps)")
    tm.add_argument("--max-fps", type=nonneg_float, default=0.0,
                    help="with --fast: at most this many frames per second (default: no cap)")
    tm.add_argument("--loop", type=nonneg_int, default=1,
                    help="play the stream this many times, continuing time and Seq (0 = forever)")
    tm.add_argument("--start", type=nonneg_float, default=0.0, help="skip the first START s of the input")
    tm.add_argument("--stop", type=finite_float, default=None, help="end STOP s after the input's beginning")
    p.add_argument("--no-mag", action="store_true", help="recordings: leave the magnetometer out")
    p.add_argument("--send-timeout", type=nonneg_float, default=0.05,
                   help="seconds to wait for room in the transmit queue before a frame counts as "
                        "failed (default 0.05)")
    p.add_argument("--stats", metavar="FILE", help="write what was sent (counts, failures) as JSON")
    p.add_argument("--started-file", metavar="FILE",
                   help="create FILE when the first frame goes out (to time things in scripts)")
    p.add_argument("--mark", action="append", default=[], metavar="S:FILE",
                   help="create FILE just before the first frame S seconds or more after the "
                        "stream's first one goes out (repeatable; to time things in scripts by "
                        "the stream, whatever the replay's lag behind the clock)")


# ---------------------------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------------------------
def _window(t: np.ndarray, start: float, stop: Optional[float]) -> np.ndarray:
    t0 = t[0] if t.size else 0.0
    keep = t - t0 >= start
    if stop is not None:
        keep &= t - t0 < stop
    return keep


def frames_from_recording(path: str, start: float = 0.0, stop: Optional[float] = None,
                          use_mag: bool = True) -> Frames:
    """The input frames of a recording file (see the command's description)."""
    from .. import canproto
    from ..io import read_recording
    rec = read_recording(path)
    if rec.t[0] < 0:
        raise InputError(f"{path}: {rec.where(0)}: sample times must be >= 0 s (first is {rec.t[0]:g})")
    keep = _window(rec.t, start, stop)
    idx = np.nonzero(keep)[0]
    if idx.size == 0:
        raise InputError(f"{path}: no samples between --start {start:g} s and --stop {stop} s "
                         f"(the recording is {rec.t[-1] - rec.t[0]:.6g} s long)")
    lo, hi = int(idx[0]), int(idx[-1]) + 1
    mag = rec.mag[lo:hi] if (use_mag and rec.mag is not None) else None
    enc = canproto.encode_samples(rec.t[lo:hi], rec.gyr[lo:hi], rec.acc[lo:hi], mag, seq0=lo)
    return Frames(t=enc.t, ids=enc.ids.astype(np.int64), data=[bytes(r) for r in enc.data],
                  extended=np.zeros(len(enc), bool), samples=hi - lo, saturated=enc.saturated)


def frames_from_canlog(path: str, start: float = 0.0, stop: Optional[float] = None) -> Frames:
    """Every classic data frame of a CAN log with its time stamp (canlog.read_frames)."""
    t, ids, data, ext = [], [], [], []
    for ti, fid, d, e in read_frames(path):
        t.append(ti)
        ids.append(fid)
        data.append(d)
        ext.append(e)
    ta = np.asarray(t)
    if np.any(np.diff(ta) < 0):
        k = int(np.argmax(np.diff(ta) < 0)) + 1
        raise InputError(f"{path}: data frame {k + 1}: time stamp goes backwards ({ta[k]:f} after "
                         f"{ta[k - 1]:f}); a log is replayed in time order")
    keep = _window(ta, start, stop)
    if not keep.any():
        raise InputError(f"{path}: no frames between --start {start:g} s and --stop {stop} s "
                         f"(the log spans {ta[-1] - ta[0]:.6g} s)")
    sel = np.nonzero(keep)[0]
    return Frames(t=ta[sel], ids=np.asarray(ids, np.int64)[sel], data=[data[i] for i in sel],
                  extended=np.asarray(ext)[sel])


def load_frames(path: str, start: float = 0.0, stop: Optional[float] = None,
                use_mag: bool = True) -> Frames:
    ext = os.path.splitext(path)[1].lower()
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    if ext in RECORDING_EXT:
        return frames_from_recording(path, start, stop, use_mag)
    if ext in CANLOG_EXT:
        return frames_from_canlog(path, start, stop)
    raise InputError(f"{path}: unknown input format '{ext or '(none)'}' (expected "
                     f"{', '.join(RECORDING_EXT + CANLOG_EXT)})")


def loop_period(fr: Frames) -> float:
    """Time added per loop: the stream's length plus one typical frame-time step, so that a
    looped stream continues without a gap or an overlap."""
    if len(fr) < 2:
        return 1e-3
    steps = np.diff(np.unique(fr.t))
    step = float(np.median(steps)) if steps.size else 1e-3
    return float(fr.t[-1] - fr.t[0]) + step


def iterate_loops(fr: Frames, loops: int, is_recording: bool) -> Iterator[Tuple[float, int, bytes, bool]]:
    """(t, id, data, extended) over all loops. Recordings get Seq and TimeUs continued."""
    from .. import canproto
    period = loop_period(fr)
    k = 0
    sync_id = canproto.frame_id("IMU_SYNC")
    while loops == 0 or k < loops:
        if k == 0 or not is_recording:
            for i in range(len(fr)):
                yield float(fr.t[i]) + k * period, int(fr.ids[i]), fr.data[i], bool(fr.extended[i])
        else:
            # Re-stamp Seq (+k*samples) and TimeUs (+k*period) of every frame.
            dseq = k * fr.samples
            dt_us = int(round(k * period * 1e6))
            for i in range(len(fr)):
                b = bytearray(fr.data[i])
                fid = int(fr.ids[i])
                if fid == sync_id:
                    tu = (int.from_bytes(b[0:4], "little") + dt_us) & 0xFFFFFFFF
                    b[0:4] = tu.to_bytes(4, "little")
                    seq = (int.from_bytes(b[4:6], "little") + dseq) & 0xFFFF
                    b[4:6] = seq.to_bytes(2, "little")
                else:
                    seq = (int.from_bytes(b[6:8], "little") + dseq) & 0xFFFF
                    b[6:8] = seq.to_bytes(2, "little")
                yield float(fr.t[i]) + k * period, fid, bytes(b), False
        k += 1


# ---------------------------------------------------------------------------------------------
# Sending
# ---------------------------------------------------------------------------------------------
@dataclass
class SendStats:
    frames: int = 0
    failed: int = 0
    retried: int = 0
    errors: Dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    first_failure_s: Optional[float] = None
    last_failure_s: Optional[float] = None

    def as_dict(self) -> Dict[str, object]:
        return {"frames": self.frames, "failed": self.failed, "retried": self.retried,
                "errors": self.errors, "seconds": round(self.seconds, 6),
                "frames_per_s": round(self.frames / self.seconds, 1) if self.seconds > 0 else None,
                "first_failure_s": self.first_failure_s, "last_failure_s": self.last_failure_s}


def check_interface(interface: str, channel: Optional[str] = None) -> None:
    """UsageError for an interface name python-can does not know, or one without a channel:
    only `virtual` has a usable default (socketcan without one would bind to every CAN
    interface, where nothing can be sent); a channel in python-can's own configuration
    (CAN_CHANNEL, ~/.canrc) counts as given."""
    import can
    if interface not in can.VALID_INTERFACES:
        raise UsageError(f"-i {interface}: unknown python-can interface (known: "
                         f"{', '.join(sorted(can.VALID_INTERFACES))})")
    if channel is None and interface != "virtual":
        try:
            configured = can.util.load_config(config={"interface": interface}).get("channel")
        except Exception:   # a malformed python-can configuration: as if none
            configured = None
        if configured in (None, ""):
            raise UsageError(f"-i {interface} needs -c/--channel (the CAN interface, e.g. vcan0 or can0)")


def open_bus(interface: str, channel: Optional[str], bitrate: Optional[int] = None):
    """A python-can bus; UsageError for an unknown interface, DeviceError when it cannot be
    opened (one line each)."""
    import can
    check_interface(interface, channel)
    kwargs = {"interface": interface}
    if channel is not None:
        kwargs["channel"] = channel
    if bitrate is not None:
        kwargs["bitrate"] = bitrate
    try:
        return can.Bus(**kwargs)
    except Exception as e:  # interfaces raise CanError, OSError, ValueError, ImportError, ...
        hint = ""
        if getattr(e, "errno", None) == errno.EAFNOSUPPORT:
            hint = " (this kernel has no CAN support: run in a guest with vcan0, tests/vm/vcan_run.py, docs/hil.md)"
        raise DeviceError(f"cannot open {interface} channel {channel}: {e or type(e).__name__}{hint}") from None


def _raw_socket(bus):
    """The CAN_RAW socket of a python-can socketcan bus (None for other interfaces). Frames are
    then written to it directly: python-can's send() adds a select() and a Message object per
    frame, which costs more than the write itself on slow machines (user-mode Linux)."""
    sock = getattr(bus, "socket", None)
    if type(bus).__name__ != "SocketcanBus" or sock is None:
        return None
    return sock


_CAN_FRAME = None


def _pack_frame(fid: int, data: bytes, ext: bool) -> bytes:
    """struct can_frame: id (EFF flag for 29-bit ids), length, 3 pad bytes, 8 data bytes."""
    import struct
    global _CAN_FRAME
    if _CAN_FRAME is None:
        _CAN_FRAME = struct.Struct("=IB3x8s")
    return _CAN_FRAME.pack((fid | 0x80000000) if ext else fid, len(data), data.ljust(8, b"\0"))


def send_stream(bus, frames: Iterator[Tuple[float, int, bytes, bool]], total: Optional[int],
                speed: float = 1.0, fast: bool = False, max_fps: float = 0.0,
                send_timeout: float = 0.05, quiet: bool = False,
                stop_flag: Optional[List[bool]] = None, started_file: Optional[str] = None,
                marks: Sequence[Tuple[float, str]] = ()) -> SendStats:
    """Sends frames paced at their time stamps / speed (or as fast as allowed). Frames with the
    same time stamp (the frames of one sample) go out back to back. marks [(S, FILE)]: each FILE
    is created just before the first frame S seconds or more into the stream goes out."""
    import can
    from ..progress import bar
    st = SendStats()
    raw = _raw_socket(bus)
    t_first = None
    t_last = None
    marks = sorted(marks)
    wall0 = time.perf_counter()
    min_gap = 1.0 / max_fps if (fast and max_fps > 0) else 0.0
    next_slot = wall0
    pb = bar(total, "replay", quiet=quiet, unit="frame")
    pending_bar = 0

    def failed(key: str) -> None:
        st.errors[key] = st.errors.get(key, 0) + 1
        st.failed += 1
        now_s = round(time.perf_counter() - wall0, 6)
        if st.first_failure_s is None:
            st.first_failure_s = now_s
        st.last_failure_s = now_s

    try:
        for t, fid, data, ext in frames:
            if t_first is None:
                t_first = t
                if started_file:
                    open(started_file, "w").close()
                wall0 = time.perf_counter()
                next_slot = wall0
            if t != t_last or min_gap > 0:
                t_last = t
                if stop_flag and stop_flag[0]:
                    break
                if not fast:
                    delay = wall0 + (t - t_first) / speed - time.perf_counter()
                    if delay > 0:
                        time.sleep(delay)
                elif min_gap > 0:
                    now = time.perf_counter()
                    if next_slot > now:
                        time.sleep(next_slot - now)
                    next_slot = max(next_slot, now - 0.01) + min_gap  # small catch-up bursts only
                while marks and t - t_first >= marks[0][0]:
                    open(marks[0][1], "w").close()
                    marks = marks[1:]
            if raw is not None:
                frame = _pack_frame(fid, data, ext)
                deadline = None
                while True:
                    try:
                        raw.send(frame)
                        st.frames += 1
                        break
                    except OSError as e:
                        if e.errno in (errno.ENOBUFS, errno.EAGAIN) and send_timeout > 0:
                            # transmit queue full (a real, slower bus): wait for room
                            now = time.perf_counter()
                            deadline = deadline or now + send_timeout
                            if now < deadline:
                                st.retried += 1
                                time.sleep(0.0005)
                                continue
                        failed(errno.errorcode.get(e.errno, str(e.errno)))
                        break
            else:
                msg = can.Message(arbitration_id=fid, data=data, is_extended_id=ext)
                try:
                    bus.send(msg, timeout=send_timeout)
                    st.frames += 1
                except can.CanError as e:
                    code = getattr(e, "error_code", None)
                    failed(errno.errorcode.get(code, str(code)) if code else type(e).__name__)
            pending_bar += 1
            if pending_bar >= 256:
                pb.update(pending_bar)
                pending_bar = 0
    finally:
        pb.update(pending_bar)
        pb.close()
        st.seconds = time.perf_counter() - wall0
    return st


def write_log(path: str, frames: Iterator[Tuple[float, int, bytes, bool]], total: Optional[int],
              quiet: bool = False) -> SendStats:
    """Writes frames to a CAN log (format from the extension), time stamps = frame times."""
    import can
    from ..errors import OutputError
    from ..progress import bar
    st = SendStats()
    t0 = time.perf_counter()
    try:
        logger = can.Logger(path)
    except (ValueError, OSError) as e:
        raise OutputError(f"{path}: cannot write a CAN log: {e}") from None
    pb = bar(total, "write", quiet=quiet, unit="frame")
    try:
        for t, fid, data, ext in frames:
            logger(can.Message(timestamp=t, arbitration_id=fid, data=data, is_extended_id=ext,
                               is_rx=False, channel="vcan0"))
            st.frames += 1
            pb.update(1)
    finally:
        pb.close()
        logger.stop()
    st.seconds = time.perf_counter() - t0
    return st


def run(args) -> int:
    from ..outputs import Outputs, check_file

    if (args.to_log is None) == (args.interface is None):
        raise UsageError("give either -i/--interface (with -c/--channel) or --to-log")
    if args.stop is not None and args.stop <= args.start:
        raise UsageError(f"--stop {args.stop:g} must be after --start {args.start:g}")
    if args.to_log is not None and args.loop == 0:
        raise UsageError("--loop 0 (forever) cannot go to a file")
    if args.interface is not None:
        check_interface(args.interface, args.channel)
    with Outputs() as out:
        out.inputs([args.input])
        if args.to_log is not None:
            check_log_name(args.to_log, "--to-log", output=True)
            out.file(args.to_log, "--to-log")
        out.file(args.stats, "--stats")
        if args.started_file:
            check_file(args.started_file, "--started-file")
        marks = [_mark(m) for m in args.mark]
        fr = load_frames(args.input, args.start, args.stop, use_mag=not args.no_mag)
        is_rec = os.path.splitext(args.input)[1].lower() in RECORDING_EXT
        total = len(fr) * args.loop if args.loop else None
        stream = iterate_loops(fr, args.loop, is_rec)
        if args.to_log:
            try:
                st = write_log(out.temp(args.to_log), stream, total, quiet=args.quiet)
            except KeyboardInterrupt:
                raise Interrupted(f"{args.to_log} not written (the log is only put in place when "
                                  "complete)") from None
            interrupted = False
        else:
            st, interrupted = _send(args, stream, total, marks)
        info = {"input": args.input, "samples": fr.samples * (args.loop or 1) if is_rec else None,
                "saturated": fr.saturated, "interrupted": interrupted, **st.as_dict()}
        if args.stats:
            with out.open(args.stats) as fh:
                json.dump(info, fh, indent=2)
                fh.write("\n")
        out.commit()
    if not args.quiet or interrupted:
        dest = args.to_log or f"{args.interface}:{args.channel}"
        sent = f"stopped after {st.frames}" + (f" of {total}" if total else "") if interrupted \
            else f"{st.frames}"
        print(f"attekf replay: {sent} frames to {dest} in {st.seconds:.2f} s"
              + (f", {st.failed} failed ({', '.join(f'{k} x{v}' for k, v in st.errors.items())})"
                 if st.failed else ""), file=sys.stderr)
        if any(fr.saturated.values()) and not args.quiet:
            print(f"attekf replay: samples with values clamped to the wire range: {fr.saturated}",
                  file=sys.stderr)
    if args.interface == "virtual":
        print(f"attekf replay: {VIRTUAL_WARNING}", file=sys.stderr)
    # a finite stream cut short ends like any interrupted command; --loop 0 only ends so
    return 130 if interrupted and args.loop else 0


def _mark(text: str) -> Tuple[float, str]:
    """--mark S:FILE checked."""
    from ..outputs import check_file
    s, sep, path = text.partition(":")
    try:
        at = float(s)
    except ValueError:
        at = -1.0
    if not sep or not (at >= 0.0) or at == float("inf"):
        raise UsageError(f"--mark {text!r}: expected S:FILE with S seconds >= 0")
    return at, check_file(path, "--mark")


def _send(args, stream, total, marks) -> Tuple[SendStats, bool]:
    """Sends the stream on the bus until done or SIGINT/SIGTERM; (stats, interrupted)."""
    stop_flag = [False]

    def on_signal(_sig, _frm):
        stop_flag[0] = True
    bus = open_bus(args.interface, args.channel, args.bitrate)
    if args.interface == "virtual":
        print(f"attekf replay: {VIRTUAL_WARNING}", file=sys.stderr)
    old_int = _set_signal(signal.SIGINT, on_signal)
    old_term = _set_signal(signal.SIGTERM, on_signal)
    try:
        st = send_stream(bus, stream, total, speed=args.speed, fast=args.fast,
                         max_fps=args.max_fps, send_timeout=args.send_timeout,
                         quiet=args.quiet, stop_flag=stop_flag, started_file=args.started_file,
                         marks=marks)
    finally:
        for sig, old in ((signal.SIGINT, old_int), (signal.SIGTERM, old_term)):
            if old is not None:
                _set_signal(sig, old)
        try:
            bus.shutdown()
        except Exception:  # noqa: BLE001 - a failing shutdown must not hide the result
            pass
    return st, stop_flag[0]
