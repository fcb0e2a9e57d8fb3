"""The estimator's output over a recording as a file: what `attekf run` writes, and
`attekf eval --save-output`.

CSV (the estimator output format that `attekf eval --output-csv` reads, with more columns):
  t_s                                        s, the recording's time of the sample
  quat_w, quat_x, quat_y, quat_z             attitude body -> output frame (ENU or NED)
  roll_rad, pitch_rad, yaw_rad               ZYX Euler angles of the same rotation
  sigma_roll_rad, sigma_pitch_rad, sigma_yaw_rad   1-sigma uncertainties, rad
  var_roll_rad2, var_pitch_rad2, var_yaw_rad2      their squares, rad^2
  gyro_bias_{x,y,z}_rad_s, gyro_bias_sigma_{x,y,z}_rad_s   gyroscope offset, body frame
  flags, status                              Flag bits; att_step's ekf_status_t (0 = OK)
Before the filter has aligned the attitude, sigma and variance cells are empty.

HDF5 (.h5, .hdf5; needs h5py): datasets t (N,), quat (N, 4), euler (N, 3), sigma (N, 3),
cov (N, 3, 3) rad^2, gyro_bias (N, 3), gyro_bias_sigma (N, 3), flags (N,), status (N, 5)
(step, predict, gyro, accel, mag); NaN angles and infinite sigmas before alignment;
attributes frame, scalar, settings (JSON), status_columns (JSON), the units in `units` (JSON).
"""

from __future__ import annotations

import json
import os
from typing import Callable, Optional

import numpy as np

from .io import COLS_EULER, COLS_QUAT, COLS_VAR, write_output_csv
from .outputs import atomic_path

EXTS = (".csv", ".h5", ".hdf5")
AXES = ("x", "y", "z")
ANGLES = ("roll", "pitch", "yaw")


def write_result_csv(path: str, res, progress: Optional[Callable[[int], None]] = None) -> None:
    """A Result (attekf.Result) as the output CSV described above."""
    aligned = res.aligned[:, None]
    var = np.where(aligned, res.var_euler, np.nan)
    sigma = np.sqrt(var)
    extra = {c: res.quat[:, k] for k, c in enumerate(COLS_QUAT)}
    extra.update({f"sigma_{a}_rad": sigma[:, k] for k, a in enumerate(ANGLES)})
    extra.update({f"gyro_bias_{a}_rad_s": res.gyro_bias[:, k] for k, a in enumerate(AXES)})
    extra.update({f"gyro_bias_sigma_{a}_rad_s": res.gyro_bias_sigma[:, k] for k, a in enumerate(AXES)})
    order = (["t_s", *COLS_QUAT, *COLS_EULER] + [f"sigma_{a}_rad" for a in ANGLES] + list(COLS_VAR)
             + [f"gyro_bias_{a}_rad_s" for a in AXES] + [f"gyro_bias_sigma_{a}_rad_s" for a in AXES]
             + ["flags", "status"])
    write_output_csv(path, res.t, res.euler, var, res.flags, res.status[:, 0], extra=extra, progress=progress,
                     order=order)


def write_result_hdf5(path: str, res) -> None:
    from .io import _h5
    h5py = _h5()
    units = {"t": "s", "quat": "1 [w x y z]", "euler": "rad", "sigma": "rad", "cov": "rad^2",
             "gyro_bias": "rad/s", "gyro_bias_sigma": "rad/s", "flags": "Flag bits", "status": "ekf_status_t"}
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        for name, data in (("t", res.t), ("quat", res.quat), ("euler", res.euler), ("sigma", res.sigma_euler),
                           ("cov", res.cov_euler), ("gyro_bias", res.gyro_bias),
                           ("gyro_bias_sigma", res.gyro_bias_sigma), ("flags", res.flags), ("status", res.status)):
            fh.create_dataset(name, data=data)
        fh.attrs["frame"] = res.frame
        fh.attrs["scalar"] = res.scalar
        fh.attrs["settings"] = json.dumps(res.settings)
        fh.attrs["status_columns"] = json.dumps(list(res.status_columns))
        fh.attrs["units"] = json.dumps(units)


def write_result(path: str, res, progress: Optional[Callable[[int], None]] = None) -> None:
    """CSV or HDF5 by the extension (EXTS)."""
    if os.path.splitext(path)[1].lower() == ".csv":
        write_result_csv(path, res, progress)
    else:
        write_result_hdf5(path, res)


__all__ = ["EXTS", "write_result", "write_result_csv", "write_result_hdf5", "COLS_EULER", "COLS_VAR"]
