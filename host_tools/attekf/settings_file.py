"""Estimator settings from a file: a TOML or a JSON object of {setting name: number}.

    # tuned.toml                          // tuned.json
    accel_noise = 0.3                     {"accel_noise": 0.3,
    mag_gate = 0                           "mag_gate": 0,
    [rest]                                 "rest": {"rest_gyro": 0.03}}
    rest_gyro = 0.03                      (or "rest.rest_gyro": 0.03)

A table (object) stands for the prefix of its settings' names ("rest.rest_gyro"). The format
follows the extension (.toml, else JSON). TOML needs Python 3.11 (tomllib) or the tomli
package. Whether a name and value are ones the filter accepts is the C library's to say
(attekf.Filter, attekf.setting_info()); here a value must be a finite number.
"""

from __future__ import annotations

import json
import math
import os
from typing import Dict, Union

from .errors import InputError

Number = Union[int, float]


def _flatten(path: str, data: dict, prefix: str, out: Dict[str, Number]) -> None:
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            _flatten(path, value, name + ".", out)
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{path}: setting '{name}': {json.dumps(value, default=str)[:40]} is not a number")
        if not math.isfinite(float(value)):
            raise InputError(f"{path}: setting '{name}': {value} is not a finite number")
        if name in out:
            raise InputError(f"{path}: setting '{name}' given twice")
        out[name] = value


def _read_text(path: str) -> str:
    from .csvtext import read_text_lines
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, expected a TOML or JSON settings file")
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    return "\n".join(read_text_lines(path))


def _toml(path: str, text: str) -> dict:
    try:
        import tomllib  # Python >= 3.11
    except ImportError:
        try:
            import tomli as tomllib  # type: ignore[no-redef]
        except ImportError:
            raise InputError(f"{path}: reading TOML needs Python >= 3.11 or the tomli package "
                             "(pip install tomli); JSON works everywhere") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML: {' '.join(str(exc).split())}") from None


def load_settings(path: Union[str, "os.PathLike[str]"]) -> Dict[str, Number]:
    """{setting name: number} from a TOML (.toml) or JSON file; attekf.io.InputError naming the
    file and the line or the setting for anything else."""
    path = os.fspath(path)
    text = _read_text(path)
    if path.lower().endswith(".toml"):
        data = _toml(path, text)
    else:
        try:
            data = json.loads(text, parse_constant=lambda c: float("nan"))
        except json.JSONDecodeError as exc:
            raise InputError(f"{path}: line {exc.lineno}: invalid JSON: {exc.msg}") from None
        except RecursionError:
            raise InputError(f"{path}: invalid JSON: nested too deeply") from None
        if not isinstance(data, dict):
            raise InputError(f"{path}: expected a JSON object {{name: value}}, got {type(data).__name__}")
    out: Dict[str, Number] = {}
    _flatten(path, data, "", out)
    return out
