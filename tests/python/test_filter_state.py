"""A Filter as a value: copy.copy and copy.deepcopy give independent filters, pickle and
get_state()/set_state() restore one bit for bit, and a state from another build, another
version or damaged bytes is refused with a clear error (host_tools/attekf/filter.py,
Core.state_bytes / load_state in host_tools/native/core_filter.c)."""

from __future__ import annotations

import copy
import pickle
import zlib

import numpy as np
import pytest

import attekf


def _samples(n, seed=0):
    rng = np.random.default_rng(seed)
    gyr = rng.normal(0.0, 0.2, (n, 3))
    acc = np.tile([0.3, -0.2, 9.7], (n, 1)) + rng.normal(0.0, 0.3, (n, 3))
    mag = np.tile([5.0, 20.0, -40.0], (n, 1)) + rng.normal(0.0, 0.5, (n, 3))
    return gyr, acc, mag


def _feed(f, gyr, acc, mag):
    return np.array([f.update(g, a, m).quaternion for g, a, m in zip(gyr, acc, mag)])


@pytest.mark.parametrize("scalar", ["float", "double", "fixed"])
@pytest.mark.parametrize("how", ["copy", "deepcopy", "pickle", "state"])
def test_a_copy_continues_exactly_and_independently(scalar, how):
    gyr, acc, mag = _samples(300)
    f = attekf.Filter({"accel_noise": 0.2}, scalar, dt=0.005, frame="NED",
                      mounting=[[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    _feed(f, gyr[:150], acc[:150], mag[:150])
    if how == "copy":
        g = copy.copy(f)
    elif how == "deepcopy":
        g = copy.deepcopy(f)
    elif how == "pickle":
        g = pickle.loads(pickle.dumps(f))
    else:
        g = attekf.Filter(scalar=scalar)          # other settings, options: all replaced
        g.set_state(f.get_state())
    assert g.get_state()["c_state"] == f.get_state()["c_state"]
    assert (g.settings, g.dt, g.frame, g.scalar) == (f.settings, f.dt, f.frame, f.scalar)
    np.testing.assert_array_equal(g.mounting, f.mounting)
    # the copy runs on alone: f is not touched by it ...
    before = f.get_state()["c_state"]
    rest_g = _feed(g, gyr[150:], acc[150:], mag[150:])
    assert f.get_state()["c_state"] == before
    # ... and both give what one filter fed everything gives
    rest_f = _feed(f, gyr[150:], acc[150:], mag[150:])
    ref = attekf.Filter({"accel_noise": 0.2}, scalar, dt=0.005, frame="NED",
                        mounting=[[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    np.testing.assert_array_equal(_feed(ref, gyr, acc, mag)[150:], rest_f)
    np.testing.assert_array_equal(rest_g, rest_f)
    assert g.diag == f.diag == ref.diag


def test_a_batch_continues_from_a_restored_state():
    gyr, acc, mag = _samples(400, seed=1)
    t = np.arange(400) * 0.01
    whole = attekf.estimate(gyr, acc, mag, t=t)
    f = attekf.Filter()
    f.update_batch(gyr[:200], acc[:200], mag[:200], t=t[:200])
    g = pickle.loads(pickle.dumps(f))            # keeps the time of the last sample too
    np.testing.assert_array_equal(g.update_batch(gyr[200:], acc[200:], mag[200:], t=t[200:]).quat,
                                  whole.quat[200:])


def _state(**change):
    f = attekf.Filter(dt=0.01)
    for _ in range(20):
        f.update([0.0, 0.0, 0.01], [0.0, 0.0, 9.81])
    s = f.get_state()
    s.update(change)
    return s


@pytest.mark.parametrize("state, fragment", [
    ("abc", "not a state saved by attekf.Filter.get_state()"),
    ({"format": "other"}, "not a state saved by attekf.Filter.get_state()"),
    (_state(version=99), "format version 99"),
    (_state(scalar="double"), "saved by a 'double' filter, this one is 'float'"),
    (_state(layout="0123456789abcdef"), "saved by another version of the estimator"),
    (_state(crc32=0), "damaged (checksum mismatch)"),
    (_state(frame="NWU"), "frame: 'NWU' is not one of ENU, NED"),
])
def test_foreign_states_are_refused(state, fragment):
    f = attekf.Filter(dt=0.02)
    before = f.get_state()
    with pytest.raises(ValueError) as err:
        f.set_state(state)
    assert fragment in str(err.value)
    assert f.get_state() == before                 # unchanged


def test_bytes_the_c_library_cannot_use_are_refused():
    """Bytes with a valid checksum but not a filter of this build: the C side checks size,
    settings (att_settings_check) and finiteness of state and covariance."""
    f = attekf.Filter(dt=0.01)
    good = _state()
    for data in (good["c_state"][:-8],                           # another size
                 b"\xff" * len(good["c_state"])):                # NaN everywhere
        bad = dict(good, c_state=data, crc32=zlib.crc32(data))
        with pytest.raises(ValueError, match="state"):
            f.set_state(bad)
    # the state of another scalar build, relabelled, is refused by its size or content
    d = attekf.Filter(scalar="double", dt=0.01).get_state()
    bad = dict(good, c_state=d["c_state"], crc32=d["crc32"])
    with pytest.raises(ValueError, match="state"):
        f.set_state(bad)
    assert f.get_state()["c_state"] == attekf.Filter(dt=0.01).get_state()["c_state"]
