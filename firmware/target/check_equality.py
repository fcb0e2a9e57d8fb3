#!/usr/bin/env python3
"""The firmware under QEMU and the host float build compute the same attitude.

Simulates a recording (attekf.sim: rotations, linear-acceleration and magnetic-disturbance
episodes, so that the de-weighting, rejection and gating branches run too), runs it through
the firmware image under QEMU (attekf_fw.elf) and through the same program built for the
host (attekf-fw-host: same application loop, same HAL backend, same float filter), both with
the same command file (the node's text commands: a live setting, a setting that waits for a
restart, the restart, a refused value, a query), and compares the outputs row by row:

  * the same rows (sample times, sequence numbers), the same status words (filter flags,
    node flags): every discrete decision was the same;
  * the same replies to the commands, and the ones expected;
  * roll, pitch and yaw within --tolerance rad on every row (yaw difference wrapped).

Prints the largest difference per angle and how many rows are bit-identical. Exit status 0
if equal within the tolerance, 1 if not, 2 on a usage or run error.

Used by ctest in the cross builds (test firmware_equals_host); by hand:
    PYTHONPATH=host_tools .venv/bin/python firmware/target/check_equality.py \\
        --firmware build/cortex-m4f/firmware/target/attekf_fw.elf \\
        --host build/host/firmware/target/attekf-fw-host --workdir out/equality
"""
import argparse
import csv
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ANGLES = ("roll_rad", "pitch_rad", "yaw_rad")
OTHER = ("sigma_roll_rad", "sigma_pitch_rad", "sigma_yaw_rad", "rate_p_rad_s", "rate_q_rad_s", "rate_r_rad_s")
EXACT = ("t_s", "flags", "node_flags", "seq")
# The node's text commands at times of the recording (firmware/app/app_text.c), and the reply
# each must give: the live one in force at once, the other pending until the restart.
COMMANDS = (
    ("10.0", "set mag_declination 0.05", "# mag_declination 0.0500000007"),
    ("10.0", "get mag_declination", "# mag_declination 0.0500000007"),
    ("20.0", "set accel_lpf_order 1", "# accel_lpf_order 1 (pending restart)"),
    ("20.0", "set gyro_noise -1", "# error: gyro_noise -1: out of range"),
    ("30.0", "restart", "# restarting"),
    ("30.0", "get accel_lpf_order", "# accel_lpf_order 1"),
)


def fail(msg, code=2):
    print(f"check_equality: {msg}", file=sys.stderr)
    sys.exit(code)


def make_recording(path, duration_s, seed):
    try:
        from attekf import io, sim
    except ImportError as e:
        fail(f"cannot import the host tools (attekf): {e}; set PYTHONPATH=host_tools")
    cfg = sim.SimConfig(duration_s=duration_s, seed=seed, lin_acc_m_s2=2.0, mag_disturbance_uT=15.0)
    io.write_recording_csv(path, sim.simulate(cfg))


def run(cmd, cwd, what):
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, stdin=subprocess.DEVNULL)
    if r.returncode != 0:
        fail(f"{what} failed (exit {r.returncode}): {' '.join(cmd)}\n{r.stdout}{r.stderr}")
    return r.stdout.strip()


def read(path):
    """The CSV rows and the reply lines ("# ...") of an output file."""
    with open(path, newline="", encoding="utf-8") as f:
        lines = f.read().splitlines()
    replies = [l for l in lines if l.startswith("#")]
    return list(csv.DictReader(l for l in lines if not l.startswith("#"))), replies


def num(cell):
    return float(cell) if cell != "" else math.nan


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--firmware", required=True, help="firmware image (attekf_fw.elf)")
    ap.add_argument("--machine", default="mps2-an386", help="QEMU board (default mps2-an386)")
    ap.add_argument("--host", required=True, help="host build of the same program (attekf-fw-host)")
    ap.add_argument("--workdir", required=True, help="directory for the recording and the outputs")
    ap.add_argument("--tolerance", type=float, default=1e-5, help="largest angle difference, rad (default 1e-5)")
    ap.add_argument("--duration", type=float, default=60.0, help="recording length, s (default 60)")
    ap.add_argument("--seed", type=int, default=7, help="simulation seed (default 7)")
    ap.add_argument("--quiet", action="store_true", help="print only the result line")
    args = ap.parse_args()

    for path, what in ((args.firmware, "firmware image"), (args.host, "host program")):
        if not os.path.isfile(path):
            fail(f"no {what} {path} (build it first: the host build for attekf-fw-host)")
    os.makedirs(args.workdir, exist_ok=True)
    rec = os.path.join(args.workdir, "recording.csv")
    make_recording(rec, args.duration, args.seed)
    with open(os.path.join(args.workdir, "commands.txt"), "w", encoding="utf-8") as f:
        f.write("# T_S COMMAND\n" + "".join(f"{t} {c}\n" for t, c, _r in COMMANDS))
    # relative names: the semihosting command line is short
    fw_out = run([os.path.join(HERE, "qemu_run.sh"), "--machine", args.machine, os.path.abspath(args.firmware),
                  "recording.csv", "out_firmware.csv", "commands.txt"], args.workdir, "firmware under QEMU")
    host_out = run([os.path.abspath(args.host), "recording.csv", "out_host.csv", "commands.txt"], args.workdir,
                   "host program")
    if not args.quiet:
        print(f"firmware: {fw_out}\nhost:     {host_out}")

    a, replies_a = read(os.path.join(args.workdir, "out_firmware.csv"))
    b, replies_b = read(os.path.join(args.workdir, "out_host.csv"))
    if len(a) != len(b) or not a:
        fail(f"{len(a)} firmware rows, {len(b)} host rows", 1)
    if replies_a != replies_b or replies_a != [r for _t, _c, r in COMMANDS]:
        fail(f"replies to the commands: firmware {replies_a}, host {replies_b}, expected "
             f"{[r for _t, _c, r in COMMANDS]}", 1)
    worst = {c: (0.0, 0) for c in ANGLES + OTHER}
    identical = 0
    aligned = 0
    for k, (ra, rb) in enumerate(zip(a, b)):
        for c in EXACT:
            if ra[c] != rb[c]:
                fail(f"row {k + 2}: {c} differs: firmware {ra[c]}, host {rb[c]}", 1)
        if all(ra[c] == rb[c] for c in ANGLES + OTHER):
            identical += 1
        for c in ANGLES + OTHER:
            x, y = num(ra[c]), num(rb[c])
            if math.isnan(x) != math.isnan(y):
                fail(f"row {k + 2}: {c}: firmware {ra[c]!r}, host {rb[c]!r}", 1)
            if math.isnan(x):
                continue
            d = abs(x - y)
            if c == "yaw_rad":
                d = abs(math.remainder(x - y, 2.0 * math.pi))
            elif c.startswith("sigma") or c.startswith("rate"):
                d = d / max(abs(y), 1e-6)  # relative
            if d > worst[c][0]:
                worst[c] = (d, k + 2)
        if ra["roll_rad"] != "":
            aligned += 1
    max_angle = max(worst[c][0] for c in ANGLES)
    if not args.quiet:
        for c in ANGLES:
            print(f"  {c:16s} max |diff| {worst[c][0]:.3e} rad (line {worst[c][1]})")
        for c in OTHER:
            print(f"  {c:16s} max relative diff {worst[c][0]:.3e} (line {worst[c][1]})")
    ok = max_angle <= args.tolerance
    print(f"check_equality: {args.machine}: {len(a)} rows ({aligned} aligned), {identical} bit-identical, "
          f"max angle difference {max_angle:.3e} rad, tolerance {args.tolerance:g}: {'PASS' if ok else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
