"""``attekf record``: log a CAN bus and decode the estimator's output frames to CSV."""

from __future__ import annotations

import json
import signal
import socket
import sys
import time
from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np

from . import set_signal as _set_signal, nonneg_float, nonneg_int
from ..errors import Interrupted, UsageError

NAME = "record"
HELP = "log a CAN bus (python-can loggers) and decode the estimator's outputs to CSV"
DESCRIPTION = """\
Listens on a python-can interface (or reads a CAN log with --from-log), writes every frame to a
log file (-o; format from the extension: .log candump, .asc, .blf, ...), and decodes with
the node's CAN database (attekf.dbc, in the package):
  --csv FILE         the node's attitude outputs (ATT_EULER, ATT_RATES, ATT_SIGMA, ATT_STATUS),
                     one row per output, in the estimator-output CSV layout (attekf run --help):
                     t_s (the time of the input sample the output includes, from its IMU_SYNC
                     frame when that was on the bus, else the bus time), roll/pitch/yaw_rad,
                     var_*_rad2 (sigma^2), flags (ATT_FLAG_*), and seq, out_index, node_flags
                     (APP_FLAG_*), rate_*_rad_s, rx_time_s (the bus timestamp, all its digits),
                     latency_s (IMU_SYNC -> ATT_EULER on
                     the bus; empty if unknown); angles, variances and rates are empty while
                     the node reports Aligned clear (it sends zeros then);
  --inputs-csv FILE  the IMU samples seen on the bus, as a recording CSV (samples without gyro or
                     accelerometer are left out and counted).
--stats writes counts, sequence gaps of inputs and outputs, the bus latency percentiles and the
node's last published counters as JSON.

Listening stops on Ctrl-C / SIGTERM, after --duration, after --idle seconds without traffic
(the node's status-only heartbeats do not count), or after --count frames; the outputs are then written. Receive errors (interface going down)
are counted and listening goes on. With --from-log, Ctrl-C abandons the run instead. Every
output is written under a temporary name and renamed when complete, so an interrupted or
failed run leaves none (and an interface that cannot be opened leaves no empty -o file).

python-can's 'virtual' interface connects only buses inside one process: nothing another
program (attekf replay, attekf-node) sends reaches `attekf record -i virtual`. Between
processes use socketcan (a vcan0 interface: ip link add vcan0 type vcan; ip link set vcan0 up).

examples:
  attekf record -i socketcan -c vcan0 -o bus.log --csv att.csv
  attekf record --from-log bus.log --csv att.csv --stats stats.json
"""

SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)


def add_arguments(p) -> None:
    src = p.add_argument_group("source (one of)")
    src.add_argument("-i", "--interface", help="python-can interface: socketcan, virtual, ...")
    src.add_argument("-c", "--channel", help="channel (vcan0, can0, ...; needed by all but virtual)")
    src.add_argument("--bitrate", type=nonneg_int, help="bitrate, for interfaces that set it")
    src.add_argument("--from-log", metavar="FILE", help="decode an existing CAN log instead of a bus")
    p.add_argument("-o", "--output", metavar="LOG", help="log every frame to this file")
    p.add_argument("--csv", metavar="FILE", help="decoded attitude outputs")
    p.add_argument("--inputs-csv", metavar="FILE", help="decoded IMU input samples (recording CSV)")
    p.add_argument("--stats", metavar="FILE", help="counts, gaps, latency and node counters as JSON")
    p.add_argument("--duration", type=nonneg_float, default=0.0, help="stop after this many seconds")
    p.add_argument("--idle", type=nonneg_float, default=0.0,
                   help="stop after this many seconds without traffic (once some was seen): the "
                        "node's status-only heartbeats and counter pages (ATT_STATUS, ATT_COUNTERS "
                        "while its input is stale) do not count")
    p.add_argument("--count", type=nonneg_int, default=0, help="stop after this many frames")
    p.add_argument("--rcvbuf", type=nonneg_int, default=8 * 1024 * 1024,
                   help="socketcan: receive buffer in bytes (default 8 MiB; bursts overflow the "
                        "kernel default)")
    p.add_argument("--ready-file", metavar="FILE", help="create FILE once listening (for scripts)")


@dataclass
class Recorder:
    """Collects frames and decodes them (inputs and outputs) in batches: while listening it only
    stores them, so that decoding does not compete with the node for the CPU during a test."""
    frames: int = 0
    by_name: Dict[str, int] = field(default_factory=dict)
    rx_errors: int = 0
    batch: int = 100000

    def __post_init__(self) -> None:
        from .. import canproto
        self.cp = canproto
        self.out = canproto.OutputDecoder()
        self.inp = canproto.InputDecoder()
        self.names = {v: k for k, v in canproto.ids().items()}
        self.sync_seen: Dict[int, float] = {}   # seq -> bus time of its IMU_SYNC (latest)
        self._raw: List[tuple] = []

    def feed(self, timestamp: float, arbitration_id: int, data: bytes, extended: bool = False) -> None:
        self.frames += 1
        self._raw.append((timestamp, arbitration_id, data, extended))
        if len(self._raw) >= self.batch:
            self.decode()

    def decode(self) -> None:
        """Decodes the frames stored so far."""
        raw, self._raw = self._raw, []
        for timestamp, arbitration_id, data, extended in raw:
            name = self.names.get(arbitration_id, "other") if not extended else "other"
            self.by_name[name] = self.by_name.get(name, 0) + 1
            if extended:
                continue
            s = self.inp.feed(timestamp, arbitration_id, data)
            if s is not None:
                self.sync_seen[s.seq] = timestamp
            self.out.feed(timestamp, arbitration_id, data)

    # -- results -----------------------------------------------------------------------------
    def input_times_us(self) -> Dict[int, int]:
        """seq -> unwrapped sample time (us) of the input samples seen."""
        if not self.inp.samples:
            return {}
        t = self.cp.unwrap_time_us([s.time_us for s in self.inp.samples])
        return {s.seq: int(ti) for s, ti in zip(self.inp.samples, t)}

    def latencies_s(self) -> np.ndarray:
        lat = []
        for r in self.out.rows:
            ts = self.sync_seen.get(r.seq)
            lat.append(r.rx_time - ts if ts is not None else np.nan)
        return np.asarray(lat, dtype=np.float64)

    def stats(self) -> Dict[str, object]:
        self.decode()
        rows = self.out.rows
        seqs = [s.seq for s in self.inp.samples]
        missing_in = 0
        for a, b in zip(seqs, seqs[1:]):
            d = (b - a) & 0xFFFF
            if 1 < d < 32768:
                missing_in += d - 1
        idx = [r.index for r in rows] + [h[2] for h in self.out.heartbeats]
        idx.sort()
        missing_out = sum(((b - a) & 0xFFFF) - 1 for a, b in zip(idx, idx[1:]) if ((b - a) & 0xFFFF) > 1)
        lat = self.latencies_s()
        lat = lat[np.isfinite(lat)] * 1e6
        pct = (lambda q: round(float(np.percentile(lat, q)), 1)) if lat.size else (lambda q: None)
        return {
            "frames": self.frames, "by_message": dict(sorted(self.by_name.items())),
            "rx_errors": self.rx_errors,
            "input_samples": len(self.inp.samples), "input_seq_missing": missing_in,
            "outputs": len(rows), "heartbeats": len(self.out.heartbeats),
            "broken_outputs": self.out.broken, "output_index_missing": missing_out,
            "latency_us": {"count": int(lat.size), "p50": pct(50), "p90": pct(90), "p99": pct(99),
                           "max": round(float(lat.max()), 1) if lat.size else None},
            "node_counters": self.out.counters,
        }

    def write_outputs_csv(self, path: str) -> str:
        """Writes the attitude outputs; returns what t_s is (for the user)."""
        from ..io import write_output_csv
        self.decode()
        rows = self.out.rows
        times = self.input_times_us()
        have_all = bool(rows) and all(r.seq in times for r in rows)
        if have_all:
            t = np.array([times[r.seq] for r in rows], dtype=np.float64) * 1e-6
            what = "input sample times"
        else:
            t = np.array([r.rx_time for r in rows], dtype=np.float64)
            what = "bus time (IMU_SYNC frames of some outputs were not on the bus)"
        n = len(rows)
        euler = np.array([r.euler for r in rows], dtype=np.float64).reshape(n, 3)
        sigma = np.array([r.sigma for r in rows], dtype=np.float64).reshape(n, 3)
        rates = np.array([r.rates for r in rows], dtype=np.float64).reshape(n, 3)
        # before alignment the node sends zeros (docs/can_protocol.md): no estimate, empty cells
        aligned = np.array([bool(r.flags & self.cp.STATUS_BITS["Aligned"]) for r in rows], bool)
        for a in (euler, sigma, rates):
            a[~aligned] = np.nan
        extra = {
            "seq": np.array([r.seq for r in rows], dtype=np.int64),
            "out_index": np.array([r.index for r in rows], dtype=np.int64),
            "node_flags": np.array([r.flags for r in rows], dtype=np.int64),
            "rate_p_rad_s": rates[:, 0], "rate_q_rad_s": rates[:, 1], "rate_r_rad_s": rates[:, 2],
            "rx_time_s": np.array([r.rx_time for r in rows], dtype=np.float64),
            "latency_s": self.latencies_s(),
        }
        write_output_csv(path, t, euler, var=sigma ** 2,
                         flags=np.array([r.att_flags for r in rows], dtype=np.int64), extra=extra,
                         full_precision=("rx_time_s",))
        return what

    def write_inputs_csv(self, path: str) -> int:
        """Writes the complete input samples as a recording; returns how many were left out."""
        from ..io import Recording, write_recording_csv
        self.decode()
        times = self.input_times_us()
        keep = [s for s in self.inp.samples if s.gyro is not None and s.accel is not None]
        t = np.array([times[s.seq] for s in keep], dtype=np.float64) * 1e-6
        gyr = np.array([s.gyro for s in keep], dtype=np.float64).reshape(len(keep), 3)
        acc = np.array([s.accel for s in keep], dtype=np.float64).reshape(len(keep), 3)
        mag = None
        if any(s.mag is not None for s in keep):
            mag = np.array([s.mag if s.mag is not None else (np.nan,) * 3 for s in keep], dtype=np.float64)
        write_recording_csv(path, Recording(t=t, gyr=gyr, acc=acc, mag=mag))
        return len(self.inp.samples) - len(keep)


def _enlarge_rcvbuf(bus, nbytes: int) -> Optional[int]:
    sock = getattr(bus, "socket", None)
    if sock is None or nbytes <= 0:
        return None
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, nbytes)
    except OSError:
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, nbytes)
        except OSError:
            return None
    return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)


def _frames_socketcan(bus, stop_flag: List[bool]):
    """Messages of a python-can socketcan bus, read from its socket without blocking: one
    system call per frame while frames flow (python-can's recv() adds a select() per frame,
    which matters on slow machines such as user-mode Linux). Yields None when idle (about every
    50 ms) and the string "error" when the socket reports one (interface down)."""
    import errno
    import select
    from can.interfaces.socketcan.socketcan import capture_message
    import can
    sock = bus.socket
    sock.setblocking(False)
    channel = bus.channel
    while not stop_flag[0]:
        try:
            msg = capture_message(sock)
        except can.CanOperationError as e:
            if e.error_code in (errno.EAGAIN, errno.EWOULDBLOCK):
                try:
                    select.select([sock], [], [], 0.05)
                except OSError:
                    yield "error"
                    time.sleep(0.02)
                yield None
            else:
                yield "error"
                time.sleep(0.02)
            continue
        if msg is not None and not msg.channel:
            msg.channel = channel
        yield msg


def _frames_generic(bus, stop_flag: List[bool]):
    import can
    while not stop_flag[0]:
        try:
            yield bus.recv(timeout=0.05)
        except can.CanError:
            yield "error"
            time.sleep(0.02)


def record_bus(rec: Recorder, bus, logger, duration: float, idle: float, count: int,
               stop_flag: List[bool], quiet: bool) -> None:
    """Logs and collects frames until a stop condition. The clock is read only when the bus is
    idle or every 256 frames. For `idle`, traffic is every frame but the node's keep-alive ones
    (ATT_STATUS and ATT_COUNTERS: alone, 10 per second, they are all a node without input sends;
    with outputs they come with ATT_EULER, which counts)."""
    from .. import canproto
    from ..progress import bar
    keepalive = {canproto.frame_id("ATT_STATUS"), canproto.frame_id("ATT_COUNTERS")}
    t0 = time.monotonic()
    last = None
    seen_since_check = 0
    traffic_since_check = 0
    source = (_frames_socketcan if type(bus).__name__ == "SocketcanBus" and getattr(bus, "socket", None)
              else _frames_generic)(bus, stop_flag)
    pb = bar(None, "record", quiet=quiet, unit="frame")
    try:
        for msg in source:
            if msg is None or msg == "error" or seen_since_check >= 256:
                now = time.monotonic()
                if traffic_since_check:
                    last = now
                    traffic_since_check = 0
                if seen_since_check:
                    pb.update(seen_since_check)
                    seen_since_check = 0
                if msg == "error":
                    rec.rx_errors += 1   # e.g. the interface went down: keep listening
                if duration > 0 and now - t0 >= duration:
                    break
                if idle > 0 and last is not None and now - last >= idle:
                    break
                if count > 0 and rec.frames >= count:
                    break
                if msg is None or msg == "error":
                    continue
            if msg.is_error_frame or msg.is_remote_frame:
                continue
            if logger is not None:
                logger(msg)
            rec.feed(float(msg.timestamp), int(msg.arbitration_id), bytes(msg.data), bool(msg.is_extended_id))
            seen_since_check += 1
            if msg.is_extended_id or msg.arbitration_id not in keepalive:
                traffic_since_check += 1
            if count > 0 and rec.frames >= count:
                break
    finally:
        pb.update(seen_since_check)
        pb.close()


VIRTUAL_WARNING = ("warning: python-can's 'virtual' interface reaches only buses in this same "
                   "process: frames another program sends (attekf replay, attekf-node) never "
                   "arrive here; between processes use -i socketcan -c vcan0")


def run(args) -> int:
    from ..canlog import LogStats, check_log_name, read_frames
    from ..outputs import Outputs, check_file
    from .replay import check_interface, open_bus

    if (args.from_log is None) == (args.interface is None):
        raise UsageError("give either -i/--interface (with -c/--channel) or --from-log")
    if not (args.output or args.csv or args.inputs_csv or args.stats):
        raise UsageError("nothing to write: give -o, --csv, --inputs-csv and/or --stats")
    if args.interface is not None:
        check_interface(args.interface, args.channel)
    with Outputs() as out:
        out.inputs([args.from_log])
        if args.output:
            check_log_name(args.output, "-o", output=True)
        for path, what in ((args.output, "-o"), (args.csv, "--csv"), (args.inputs_csv, "--inputs-csv"),
                           (args.stats, "--stats")):
            out.file(path, what)
        if args.ready_file:
            check_file(args.ready_file, "--ready-file")
        if args.from_log:
            check_log_name(args.from_log, "--from-log")
        rec = Recorder()
        stop_flag = [False]
        if args.from_log:
            logstats = LogStats()
            frames = read_frames(args.from_log, stop=stop_flag, stats=logstats)
            _record(args, rec, None, frames, out, stop_flag)
            if stop_flag[0]:
                raise Interrupted(f"after {rec.frames} frames of {args.from_log}: nothing written "
                                  "(outputs are only put in place when complete)")
            skipped = [f"{n} {k}" for k, n in (("error", logstats.error_frames), ("remote", logstats.remote_frames),
                                               ("CAN FD", logstats.fd_frames)) if n]
            if skipped and not args.quiet:
                print(f"attekf record: {args.from_log}: skipped {', '.join(skipped)} frame(s)", file=sys.stderr)
        else:
            bus = open_bus(args.interface, args.channel, args.bitrate)
            if args.interface == "virtual":
                print(f"attekf record: {VIRTUAL_WARNING}", file=sys.stderr)
            _record(args, rec, bus, None, out, stop_flag)
        _write(args, rec, out)
        out.commit()
    st = rec.stats()
    if not args.quiet:
        lat = st["latency_us"]
        print(f"attekf record: {st['frames']} frames, {st['input_samples']} input samples "
              f"({st['input_seq_missing']} missing by Seq), {st['outputs']} outputs "
              f"({st['output_index_missing']} missing by OutIndex), {st['heartbeats']} heartbeats"
              + (f"; latency p50 {lat['p50']} us, p99 {lat['p99']} us" if lat["count"] else ""),
              file=sys.stderr)
    if args.interface == "virtual" and st["frames"] == 0:
        print(f"attekf record: received no frames; {VIRTUAL_WARNING}", file=sys.stderr)
    return 0


def _record(args, rec: Recorder, bus, frames, out, stop_flag: List[bool]) -> None:
    """Feeds the recorder from the log (frames) or the bus until the end or a stop, logging
    every frame to the -o temporary file. SIGINT/SIGTERM set stop_flag meanwhile."""
    import can

    def on_signal(_sig, _frm):
        stop_flag[0] = True
    old_int = _set_signal(signal.SIGINT, on_signal)
    old_term = _set_signal(signal.SIGTERM, on_signal)
    logger = None
    try:
        if args.output:
            from ..errors import OutputError
            try:
                logger = can.Logger(out.temp(args.output))
            except (ValueError, OSError) as e:
                raise OutputError(f"{args.output}: cannot write a CAN log: {e}") from None
        if frames is not None:
            from ..progress import bar
            with bar(None, "read", quiet=args.quiet, unit="frame") as pb:
                for k, (t, fid, data, ext) in enumerate(frames):
                    if logger is not None:
                        logger(can.Message(timestamp=t, arbitration_id=fid, data=data, is_extended_id=ext))
                    rec.feed(t, fid, data, ext)
                    if k % 4096 == 4095:
                        pb.update(4096)
        else:
            try:
                got = _enlarge_rcvbuf(bus, args.rcvbuf)
                if args.ready_file:
                    open(args.ready_file, "w").close()
                if not args.quiet:
                    print(f"attekf record: listening on {args.interface}:{args.channel}"
                          + (f" (receive buffer {got} bytes)" if got else ""), file=sys.stderr)
                record_bus(rec, bus, logger, args.duration, args.idle, args.count, stop_flag, args.quiet)
            finally:
                try:
                    bus.shutdown()
                except Exception:  # noqa: BLE001 - a failing shutdown must not hide the recording
                    pass
    finally:
        if logger is not None:
            logger.stop()
        for sig, old in ((signal.SIGINT, old_int), (signal.SIGTERM, old_term)):
            if old is not None:
                _set_signal(sig, old)


def _write(args, rec: Recorder, out) -> None:
    """The decoded outputs, to their temporary files."""
    if args.csv:
        what = rec.write_outputs_csv(out.temp(args.csv))
        if not args.quiet:
            print(f"attekf record: {len(rec.out.rows)} outputs to {args.csv} (t_s = {what})", file=sys.stderr)
    if args.inputs_csv:
        left = rec.write_inputs_csv(out.temp(args.inputs_csv))
        if not args.quiet:
            print(f"attekf record: {len(rec.inp.samples) - left} input samples to {args.inputs_csv}"
                  + (f" ({left} without gyro or accelerometer left out)" if left else ""), file=sys.stderr)
    if args.stats:
        with out.open(args.stats) as fh:
            json.dump(rec.stats(), fh, indent=2)
            fh.write("\n")
