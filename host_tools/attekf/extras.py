"""Which optional Python package each part of the tools needs, and the extra of the attekf
package that installs it (pyproject.toml, [project.optional-dependencies]). The filter
itself (import attekf) needs numpy only.

    require("h5py", "HDF5 files")  ->  MissingExtra: "the Python package h5py is needed for
                                        HDF5 files: pip install 'attekf[tools]'"
"""

from __future__ import annotations

from importlib.util import find_spec
from typing import Iterable, List

from .errors import MissingExtra

# import name -> (distribution name, extra)
PACKAGES = {
    "tqdm": ("tqdm", "tools"),
    "h5py": ("h5py", "tools"),
    "matplotlib": ("matplotlib", "plots"),
    "can": ("python-can", "can"),
    "cantools": ("cantools", "can"),
    "vqf": ("vqf", "bench"),
    "imufusion": ("imufusion", "bench"),
    "ahrs": ("AHRS", "bench"),
}


def installed(module: str) -> bool:
    try:
        return find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def missing(modules: Iterable[str]) -> List[str]:
    """The modules of `modules` that cannot be imported."""
    return [m for m in modules if not installed(m)]


def message(module: str, what: str, extra: str = "") -> str:
    dist, default_extra = PACKAGES.get(module, (module, "all"))
    return f"the Python package {dist} is needed for {what}: pip install 'attekf[{extra or default_extra}]'"


def require(module: str, what: str, extra: str = "") -> None:
    """MissingExtra naming the extra to install unless `module` can be imported."""
    if not installed(module):
        raise MissingExtra(message(module, what, extra))
