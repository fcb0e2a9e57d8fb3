"""attekf: an attitude EKF for microcontrollers, and its host tools.

The estimator (the same C code as on the target, in the package's extension modules):

    import attekf
    f = attekf.Filter()                              # settings=None, scalar="float"
    est = f.update(gyr, acc, mag, dt=0.01)           # rad/s, m/s^2, uT, s
    est.quaternion, est.euler, est.sigma, est.flags  # [w x y z] body->ENU; rad; rad; Flag

    res = attekf.estimate(gyr, acc, mag, rate_hz=100.0)   # (N, 3) arrays, one C call

help(attekf.Filter), help(attekf.Estimate), help(attekf.Result) and help(attekf.filter)
explain units, frames and what is reported before the filter has aligned;
attekf.setting_info() lists the settings with their units and ranges. The import needs
numpy only. The command-line tools (attekf --help) need extras: pip install "attekf[tools]"
(sim, eval, run), "attekf[can]" (replay, record), "attekf[bench]" (bench, cv).
"""

from .filter import (Estimate, Filter, Flag, NativeError, Result, SettingsError, default_settings,
                     estimate, load_settings, setting_info)

__version__ = "0.1.0"

__all__ = ["Filter", "Estimate", "estimate", "Result", "Flag", "default_settings", "setting_info",
           "load_settings", "SettingsError", "NativeError", "__version__"]
