"""attekf.canproto: the host side of the CAN protocol (firmware/app/dbc/attekf.dbc)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from attekf import canproto as cp

REPO = Path(__file__).resolve().parents[2]


def test_vectorised_encoder_matches_cantools():
    db = cp.database()
    rng = np.random.default_rng(1)
    n = 400
    for name, sigs, _bit in cp.SENSOR_MESSAGES:
        lo, hi = cp.signal_range(name, sigs[0])
        scale = cp.resolution(name, sigs[0])
        vals = {s: rng.uniform(lo, hi, n) for s in sigs}
        # exact half-LSB values and the range ends, where rounding rules differ
        vals[sigs[0]][:6] = [lo, hi, 0.5 * scale, -0.5 * scale, 2.5 * scale, -1.5 * scale]
        vals["Seq"] = rng.integers(0, 65536, n).astype(float)
        got = cp.encode_message_vec(name, vals)
        for k in range(n):
            ref = db.encode_message(name, {s: float(v[k]) for s, v in vals.items()})
            assert bytes(got[k]) == ref, (name, k)
    sync = {"TimeUs": rng.integers(0, 2 ** 32, n).astype(float), "Seq": rng.integers(0, 65536, n).astype(float)}
    for s in ("HasGyro", "HasAccel", "HasMag", "SatGyro", "SatAccel", "SatMag"):
        sync[s] = rng.integers(0, 2, n).astype(float)
    got = cp.encode_message_vec("IMU_SYNC", sync)
    for k in range(n):
        assert bytes(got[k]) == db.encode_message("IMU_SYNC", {s: int(v[k]) for s, v in sync.items()})


def test_out_of_range_raw_is_refused_not_wrapped():
    with pytest.raises(cp.ProtocolError):
        cp.encode_message_vec("IMU_GYRO", {"GyroX": np.array([40.0]), "Seq": np.array([0.0])})


def test_encode_samples_layout_clamping_and_optional_sensors():
    t = np.array([0.0, 0.01, 0.02])
    gyr = np.array([[0.1, 0.2, 0.3], [50.0, 0, 0], [0, 0, 0]])          # 50 rad/s saturates
    acc = np.array([[0, 0, 9.81], [0, 0, 9.81], [0, -500.0, 9.81]])     # -500 m/s^2 saturates
    mag = np.array([[20, 0, -40], [np.nan] * 3, [20, 0, -40]])          # no mag in sample 1
    fr = cp.encode_samples(t, gyr, acc, mag, seq0=65535)
    names = [cp.database().get_message_by_frame_id(int(i)).name for i in fr.ids]
    assert names == ["IMU_GYRO", "IMU_ACCEL", "IMU_MAG", "IMU_SYNC",
                     "IMU_GYRO", "IMU_ACCEL", "IMU_SYNC",
                     "IMU_GYRO", "IMU_ACCEL", "IMU_MAG", "IMU_SYNC"]
    assert fr.sample.tolist() == [0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2]
    assert fr.saturated == {"gyro": 1, "accel": 1, "mag": 0}
    dec = cp.InputDecoder()
    for k in range(len(fr)):
        dec.feed(float(fr.t[k]), int(fr.ids[k]), bytes(fr.data[k]))
    s = dec.samples
    assert [x.seq for x in s] == [65535, 0, 1]                         # sequence wraps
    assert [x.time_us for x in s] == [0, 10000, 20000]
    assert s[1].mag is None and s[1].saturated == cp.HAS_GYRO
    assert s[1].gyro[0] == pytest.approx(32.767)
    assert s[2].saturated == cp.HAS_ACCEL and s[2].accel[1] == pytest.approx(-163.835)
    np.testing.assert_allclose(s[0].gyro, gyr[0], atol=0.0005 + 1e-9)
    np.testing.assert_allclose(s[0].mag, mag[0], atol=0.025 + 1e-9)


def test_quantisation_is_well_below_sensor_noise():
    # docs/can_protocol.md: uniform quantisation error, LSB/sqrt(12), against the noise levels
    for (msg, sig), noise in {("IMU_GYRO", "GyroX"): 0.005, ("IMU_ACCEL", "AccelX"): 0.05,
                              ("IMU_MAG", "MagX"): 0.3}.items():
        assert cp.resolution(msg, sig) / np.sqrt(12) < noise / 10


def test_signal_ranges_are_symmetric_full_int16():
    # The C side takes the wire limits from the generated decoders at INT16_MAX: the DBC's
    # min/max must be exactly +-32767 LSB for that to hold.
    for name, sigs, _ in cp.SENSOR_MESSAGES:
        for s in sigs:
            lo, hi = cp.signal_range(name, s)
            assert hi == pytest.approx(32767 * cp.resolution(name, s)) and lo == -hi


def test_times_before_zero_are_refused():
    with pytest.raises(cp.ProtocolError):
        cp.time_us(np.array([-1.0, 0.0]))


def test_unwrap_time():
    raw = np.array([2 ** 32 - 200, 2 ** 32 - 100, 0, 100]) & 0xFFFFFFFF
    assert cp.unwrap_time_us(raw).tolist() == [2 ** 32 - 200, 2 ** 32 - 100, 2 ** 32, 2 ** 32 + 100]


def test_output_schedule():
    t = np.arange(0, 100) * 3500          # 285.7 Hz
    idx = cp.output_schedule(t, 10000)
    assert idx[:5].tolist() == [0, 3, 6, 9, 12]
    assert np.all(np.diff(t[idx]) >= 7000)
    assert cp.output_schedule(t, 0).tolist() == list(range(100))


def test_output_decoder_pairs_frames_and_counts_broken_outputs():
    db = cp.database()
    dec = cp.OutputDecoder()
    e = db.encode_message("ATT_EULER", {"Roll": 0.1, "Pitch": -0.2, "Yaw": 3.0, "Seq": 7})
    r = db.encode_message("ATT_RATES", {"RateP": 0, "RateQ": 0, "RateR": 1.0, "Seq": 7})
    s = db.encode_message("ATT_SIGMA", {"SigmaRoll": 0.01, "SigmaPitch": 0.01, "SigmaYaw": 0.2, "Seq": 7})
    bits = {k: 0 for k in cp.STATUS_BITS}
    st = db.encode_message("ATT_STATUS", {**bits, "Aligned": 1, "Gap": 1, "AttFlags": 5, "Seq": 7, "OutIndex": 3})
    for i, d in ((0x180, e), (0x181, r), (0x182, s), (0x183, st)):
        dec.feed(1.0, i, d)
    assert len(dec.rows) == 1
    row = dec.rows[0]
    assert row.seq == 7 and row.index == 3 and row.att_flags == 5
    assert row.flags == cp.STATUS_BITS["Aligned"] | cp.STATUS_BITS["Gap"]
    assert row.euler == pytest.approx((0.1, -0.2, 3.0))
    # a status whose estimate frames are missing is a broken output, not a row
    dec.feed(2.0, 0x183, st)
    assert len(dec.rows) == 1 and dec.broken == 1
    c = db.encode_message("ATT_COUNTERS", {"Page": 3, "Duplicate": 42})
    dec.feed(2.0, 0x184, c)
    assert dec.counters == {"duplicate": 42}


def test_generated_files_are_current():
    assert cp.main(["check"]) == 0


def test_check_detects_stale_generated_code(tmp_path):
    for rel in ("firmware/app/dbc", "docs", "firmware/att"):
        shutil.copytree(REPO / rel, tmp_path / rel)
    shutil.copy(REPO / "firmware/app/app_msg.h", tmp_path / "firmware/app/app_msg.h")
    assert cp.main(["check", "--root", str(tmp_path)]) == 0
    c = tmp_path / "firmware/app/dbc/canmsg_gen.c"
    c.write_text(c.read_text().replace("0.001f", "0.002f", 1))
    assert cp.main(["check", "--root", str(tmp_path)]) == 1
    assert cp.main(["generate", "--root", str(tmp_path)]) == 0
    assert cp.main(["check", "--root", str(tmp_path)]) == 0


def test_check_detects_headers_that_drift_from_the_dbc(tmp_path):
    """A flag bit or counter changed in the C headers without the DBC fails the check."""
    for rel in ("firmware/app/dbc", "docs", "firmware/att"):
        shutil.copytree(REPO / rel, tmp_path / rel)
    app_h = tmp_path / "firmware/app/app_msg.h"
    text = (REPO / "firmware/app/app_msg.h").read_text()
    for mutated in (text.replace("APP_FLAG_GAP            (1u << 2)", "APP_FLAG_GAP            (1u << 13)"),
                    text.replace("X(FOREIGN, foreign,", "X(UNKNOWN_ID, unknown_id,")):
        assert mutated != text
        app_h.write_text(mutated)
        assert cp.main(["check", "--root", str(tmp_path)]) == 1
    app_h.write_text(text)
    assert cp.main(["check", "--root", str(tmp_path)]) == 0
    att_h = tmp_path / "firmware/att/att.h"
    att_h.write_text(att_h.read_text().replace("#define ATT_FLAG_AT_REST          (1u << 13)",
                                               "#define ATT_FLAG_AT_REST          (1u << 14)"))
    assert cp.main(["check", "--root", str(tmp_path)]) == 1


def test_missing_dbc_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setenv("ATTEKF_DBC", str(tmp_path / "nope.dbc"))
    with pytest.raises(cp.ProtocolError, match="nope.dbc"):
        cp.dbc_path()
