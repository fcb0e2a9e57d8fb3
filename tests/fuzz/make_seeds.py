"""Writes the committed seed corpora of the fuzz targets (tests/fuzz/corpus/<target>/).

    python3 tests/fuzz/make_seeds.py

Each seed is a small, well-formed input in the target's input language (see the target's
header comment), so the fuzzer starts from inputs that reach deep states (an aligned filter,
complete samples, outputs) and mutates from there. Deterministic: re-running rewrites the
same files.
"""
import math
import os
import re
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as fh:
        fh.write(bytes(data))


def real16(value, scale):
    """fz_real encoding of an ordinary value: kind byte 0, int16 = value / scale * 16384."""
    q = max(-32768, min(32767, int(round(value / scale * 16384.0))))
    return bytes([0]) + struct.pack("<h", q)


# ---- fuzz_att: settings byte < 64 = defaults (else 64 + changes), then samples ---------------
def setting_rows():
    """The rows of att_settings_table.h in att_setting_info order: main, then rest.*, bias.*."""
    text = open(os.path.join(HERE, "..", "..", "firmware", "att", "att_settings_table.h")).read()
    body = text[text.index("#define ATT_SETTINGS_MAIN"):]
    rest, bias = body.index("#define ATT_SETTINGS_REST"), body.index("#define ATT_SETTINGS_BIAS")
    return [("" if m.start() < rest else "rest." if m.start() < bias else "bias.") + m.group(1)
            for m in re.finditer(r"X\((\w+),", body)]


ROWS = setting_rows()


def change(name, how, t=0):
    """One settings change of fuzz_att.c: how < 96 a value within the range (t: its place,
    0..255), 96..159 a bound (t < 128 the lower one)."""
    return bytes([ROWS.index(name), how, t])


def att_settings(changes):
    return bytes([64 + len(changes)]) + b"".join(changes)


def att_structured(n, dtk, rates, tilt, settings=b"\0"):
    out = bytearray(settings)  # default settings unless given
    for k in range(n):
        g = rates(k)
        out += bytes([dtk, 0x87, tilt(k) & 0xFF, g[0] & 0xFF, g[1] & 0xFF, g[2] & 0xFF])
    return out


def att_free(n, dtk):
    out = bytearray([0])
    for k in range(n):
        out += bytes([dtk, 0x07])
        for v, s in ((0.01, 5.0), (-0.02, 5.0), (0.03, 5.0)):
            out += real16(v, s)
        for v, s in ((0.3, 20.0), (-0.2, 20.0), (9.8, 20.0)):
            out += real16(v, s)
        for v, s in ((20.0, 60.0), (5.0, 60.0), (-40.0, 60.0)):
            out += real16(v, s)
    return out


write("fuzz_att", "rest", att_structured(60, 47, lambda k: (0, 0, 0), lambda k: 0))   # dt ~ 1 ms
write("fuzz_att", "turning", att_structured(120, 47, lambda k: (10, -5, 20), lambda k: 4))
write("fuzz_att", "pitch_loop", att_structured(200, 95, lambda k: (0, 30, 0), lambda k: 60))
write("fuzz_att", "free_values", att_free(40, 47))
# settings within their ranges, and at the bounds the issue of the filter's promises named
settings = att_settings([change("rate_walk", 0, 90), change("accel_lpf_order", 0, 0), change("bias.motion", 0, 128),
                         change("rest.bias_tau", 0, 40), change("mag_reset_time", 0, 30),
                         change("accel_adapt_tau", 0, 60)])
write("fuzz_att", "settings", att_structured(40, 47, lambda k: (3, 3, 3), lambda k: 8, settings))
bounds = att_settings([change("euler_rate_rel", 96, 255), change("bias.walk", 96, 255), change("dt_max", 96, 255),
                       change("bias.sigma_init", 96, 0), change("accel_lpf_order", 96, 255),
                       change("angle_walk_rate", 96, 255), change("mag_reset_time", 96, 0)])
write("fuzz_att", "settings_bounds", att_structured(60, 150, lambda k: (20, -9, 5), lambda k: 20, bounds))


def setting_count():
    """Rows of firmware/att/att_settings_table.h (the table fuzz_att's mode 240 walks)."""
    path = os.path.join(HERE, "..", "..", "firmware", "att", "att_settings_table.h")
    with open(path) as fh:
        return sum(1 for line in fh if line.lstrip().startswith("X("))


def att_table(choice):
    """Mode 240: one byte per setting (< 128 default, 128 lower bound, 160 upper bound)."""
    return bytearray([240]) + bytes(choice(i) for i in range(setting_count()))


motion = att_structured(80, 47, lambda k: (6, -4, 9), lambda k: 12)[1:]
write("fuzz_att", "settings_table_lower", att_table(lambda i: 128 if i % 7 == 3 else 0) + motion)
write("fuzz_att", "settings_table_upper", att_table(lambda i: 160 if i % 7 == 5 else 0) + motion)


# ---- fuzz_can: op 2 = a sample encoded as the IMU does --------------------------------
def can_sample(mode=0, valid=7, dt_byte=20):
    out = bytearray([2, dt_byte, mode, valid])
    for gv, av, mv in ((0.01, 0.3, 20.0), (-0.02, -0.2, 5.0), (0.03, 9.81, -40.0)):
        out += real16(gv, 10.0) + real16(av, 20.0) + real16(mv, 50.0)
    return out


write("fuzz_can", "clean", b"".join(can_sample() for _ in range(40)) + bytes([5, 0]))
write("fuzz_can", "faults",
      b"".join(can_sample(mode=m) for m in (0, 0x08, 0x20, 0x02, 0x01, 0, 0x28, 0)) * 4 + bytes([6, 0, 5, 0]))
write("fuzz_can", "raw_frames",
      bytes([0, 10, 0xFF]) + bytes(8) + bytes([0x18, 10, 0x03]) + bytes(8) + bytes([7, 10, 3, 8]) + bytes(8))


# ---- fuzz_socketcan: batches of messages -----------------------------------------------
def gyro(seq):
    return struct.pack("<hhhH", 10, -20, 30, seq)


def accel(seq):
    return struct.pack("<hhhH", 60, -40, 1962, seq)


def mag(seq):
    return struct.pack("<hhhH", 400, 100, -800, seq)


def sync(seq, t_us):
    return struct.pack("<IHBB", t_us & 0xFFFFFFFF, seq, 0x07, 0)


def sc_batch(first_seq, n):
    out = bytearray([4 * n - 1, 0])  # batch size - 1, mm byte (even: realistic clock offset)
    out += struct.pack("<I", 1000)   # mono_minus_real / 1000
    for s in range(first_seq, first_seq + n):
        for idx, payload in ((0, gyro(s)), (1, accel(s)), (2, mag(s)), (3, sync(s, 1000 * s))):
            shape = (idx << 1) | 0x40  # structured id, with a receive time
            out += bytes([shape]) + payload
            out += bytes([1, 0]) + struct.pack("<HI", s, 1000 * s * 1000 % 1000000000)
            out += bytes([0])  # no truncated control data
    out += bytes([0])  # no publish
    return out


write("fuzz_socketcan", "clean", sc_batch(0, 8) + sc_batch(8, 8))
write("fuzz_socketcan", "overflow", bytes(sc_batch(0, 4)).replace(bytes([0x46]), bytes([0xC6]), 1))

# ---- fuzz_parsers (atheris): kind byte, then the file -----------------------------------
rec = ("t_s,gyr_x_rad_s,gyr_y_rad_s,gyr_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2,mag_x_uT,mag_y_uT,mag_z_uT\n"
       + "".join(f"{k * 0.01:.2f},0.01,0.02,-0.01,0.1,0.2,9.8,20,5,-40\n" for k in range(5)))
write("fuzz_parsers", "recording_csv", b"\x00\x00" + rec.encode())
out = ("t_s,roll_rad,pitch_rad,yaw_rad,var_roll_rad2,var_pitch_rad2,var_yaw_rad2,flags,status\n"
       + "".join(f"{k * 0.01:.2f},0.1,0.2,0.3,1e-4,1e-4,1e-3,1,0\n" for k in range(5)))
write("fuzz_parsers", "output_csv", b"\x01\x00" + out.encode())
log = "".join(f"({k * 0.001:.6f}) vcan0 103#{(k * 1000):08X}{k:04X}0700\n" for k in range(5))
write("fuzz_parsers", "candump_log", b"\x03\x00" + log.encode())

# ---- fuzz_candump: candump log text as attekf-node replays it ----------------------------
write("fuzz_candump", "lines", b"(1700000000.123456) vcan0 123#0011AAFF\n(0.000001) can0 1FFFFFFF#\n"
      b"# comment\n(5.000000) vcan0 123#R\n(5.000000) vcan0 123##1AABB\n"
      b"(5.1234567) x 7FF#0102030405060708\n")
write("fuzz_candump", "replay_log", log.encode())
print("seeds written under", os.path.join(HERE, "corpus"))
