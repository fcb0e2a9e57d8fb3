"""The Python package as a user gets it: its sdist, installed into a fresh virtual environment
outside the repository, with the `bench` extra.

One sdist is built from host_tools/ (scikit-build-core, pinned in requirements.lock), pip turns
it into a wheel (CMake compiles the float, double and fixed-point libraries; the wheel is kept
under build/package-test/, keyed by the sdist's SHA-256, so an unchanged sdist is not rebuilt),
and a new virtual environment in a temporary directory installs it with its dependencies from
the package registry (pinned by requirements.lock as constraints). Every command and the API
then run from a working directory outside the repository with no ATTEKF_* variables, and the
results must equal those of the source tree's build (build/host) bit for bit.

Run by scripts/test.sh as its own step.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tarfile
import venv
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
HOST_TOOLS = REPO / "host_tools"
CACHE = REPO / "build" / "package-test"
LOCK = HOST_TOOLS / "requirements.lock"


def _clean_env(extra_path: Path | None = None) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("ATTEKF_") and k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    if extra_path is not None:
        env["PATH"] = f"{extra_path}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    return env


def _run(cmd, cwd: Path, env: dict, timeout: float = 600) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0:
        pytest.fail(f"{' '.join(str(c) for c in cmd)} exited {proc.returncode}\n"
                    f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}", pytrace=False)
    return proc


class Installed:
    def __init__(self, root: Path, sdist: Path):
        self.root = root
        self.sdist = sdist
        self.venv = root / "venv"
        self.bin = self.venv / "bin"
        self.python = self.bin / "python"
        self.work = root / "work"
        self.env = _clean_env(self.bin)

    def run(self, *args, **kw) -> subprocess.CompletedProcess:
        return _run(args, self.work, kw.pop("env", self.env), **kw)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Installed:
    root = tmp_path_factory.mktemp("attekf-package")
    assert REPO not in root.parents, "the test environment must be outside the repository"
    # 1. the sdist, once
    dist = root / "dist"
    _run([sys.executable, "-c", "import sys, scikit_build_core.build as b; b.build_sdist(sys.argv[1])", dist],
         HOST_TOOLS, _clean_env())
    (sdist,) = dist.glob("attekf-*.tar.gz")
    inst = Installed(root, sdist)
    inst.work.mkdir()
    # A virtual environment of its own; the source tree's pip installs into it (--python),
    # which saves bootstrapping a pip into every new environment.
    venv.EnvBuilder(with_pip=False).create(inst.venv)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    # 2. the wheel pip builds from the sdist (isolated build: scikit-build-core from the
    #    registry, then CMake), cached by the sdist's content
    digest = hashlib.sha256(sdist.read_bytes()).hexdigest()[:16]
    wheels = CACHE / digest
    if not list(wheels.glob("attekf-*.whl")):
        for old in CACHE.glob("[0-9a-f]" * 16):   # wheels of earlier sdists
            shutil.rmtree(old, ignore_errors=True)
        _run(pip + ["wheel", "--no-deps", "-w", root / "wheel", sdist], inst.work, inst.env)
        wheels.mkdir(parents=True)
        for w in (root / "wheel").glob("attekf-*.whl"):
            shutil.copy2(w, wheels)
    (wheel,) = wheels.glob("attekf-*.whl")
    # 3. installed with its dependencies and the bench extra, versions pinned by the lock;
    #    the dependencies' wheels are kept in build/package-test/wheelhouse (filled from the
    #    registry when one is missing)
    house = CACHE / "wheelhouse"
    req = [f"{wheel}[bench]", "-c", LOCK]
    install = pip + ["--python", inst.python, "install", "--no-index", "--find-links", house] + req
    proc = subprocess.run([str(c) for c in install], cwd=inst.work, env=inst.env, capture_output=True,
                          text=True, timeout=600)
    if proc.returncode != 0:
        _run(pip + ["download", "-d", house] + req, inst.work, inst.env)
        for w in house.glob("attekf-*"):     # only the dependencies are kept there
            w.unlink()
        _run(install, inst.work, inst.env)
    return inst


def test_sdist_carries_the_c_sources_and_nothing_of_the_build(installed):
    with tarfile.open(installed.sdist) as tar:
        names = tar.getnames()
    top = names[0].split("/")[0]
    rel = {n[len(top) + 1:] for n in names}
    for needed in ("pyproject.toml", "CMakeLists.txt", "native/attekf_native.c", "attekf/filter.py",
                   "csrc/CMakeLists.txt", "csrc/firmware/CMakeLists.txt", "csrc/firmware/att/att.c",
                   "csrc/firmware/ekf/ekf.c", "csrc/firmware/app/dbc/attekf.dbc", "csrc/cmake/Warnings.cmake"):
        assert needed in rel, f"sdist lacks {needed}"
    assert not [n for n in rel if "__pycache__" in n or ".egg-info" in n or n.startswith(("build/", "csrc/build"))]
    assert "requirements.lock" not in rel


def test_installed_package_uses_its_own_libraries_and_dbc(installed):
    out = installed.run(installed.python, "-c",
                        "import attekf.native as n, attekf.canproto as c; print(n.load('float').path); "
                        "print(n.load('fixed').path); print(c.dbc_path())").stdout.split()
    site = installed.venv.resolve()
    for p in out:
        assert site in Path(p).resolve().parents, f"{p} is not inside the virtual environment"
    # the overrides still win
    env = dict(installed.env, ATTEKF_LIB=str(REPO / "build" / "host" / "host_tools" / "native"),
               ATTEKF_DBC=str(REPO / "hal" / "can" / "attekf.dbc"))
    out = installed.run(installed.python, "-c",
                        "import attekf.native as n, attekf.canproto as c; print(n.load('double').path); "
                        "print(c.dbc_path())", env=env).stdout.split()
    assert Path(out[0]).parent == Path(env["ATTEKF_LIB"]) and Path(out[1]) == Path(env["ATTEKF_DBC"])


def test_every_command_works_outside_the_repository(installed):
    attekf = installed.bin / "attekf"
    installed.run(attekf, "sim", "-q", "rec.csv", "--duration", "20", "--seed", "5")
    installed.run(attekf, "sim", "-q", "trials/trial01.hdf5", "--duration", "10", "--seed", "6")
    # eval: the same numbers, and the same output file byte for byte, as the source tree's build
    installed.run(attekf, "eval", "-q", "rec.csv", "--no-plot", "--out", "eval_pkg", "--save-output")
    _run([REPO / ".venv" / "bin" / "attekf", "eval", "-q", "rec.csv", "--no-plot", "--out", "eval_tree",
          "--save-output"], installed.work, _clean_env())
    w = installed.work
    assert (w / "eval_pkg" / "rec_output.csv").read_bytes() == (w / "eval_tree" / "rec_output.csv").read_bytes()
    pkg = json.loads((w / "eval_pkg" / "results.json").read_text())["trials"][0]
    tree = json.loads((w / "eval_tree" / "results.json").read_text())["trials"][0]
    for key in ("rmse_deg", "within_3sigma_pct", "counts", "estimator_summary"):
        assert pkg[key] == tree[key], key
    # replay -> CAN log -> record: the packaged DBC encodes and decodes the samples
    installed.run(attekf, "replay", "-q", "rec.csv", "--to-log", "frames.log")
    installed.run(attekf, "record", "-q", "--from-log", "frames.log", "--inputs-csv", "inputs.csv",
                  "--stats", "stats.json")
    def data_rows(name):
        lines = [r for r in (w / name).read_text().splitlines() if r and not r.startswith("#")]
        return lines[1:]  # after the header (sim's CSV starts with "# key: value" lines)
    assert len(data_rows("inputs.csv")) == len(data_rows("rec.csv")) == 2001
    # bench with the [bench] extra: ours and every baseline on a simulated trial
    installed.run(attekf, "bench", "-q", "--data", "trials", "--jobs", "1", "--no-plot", "--json", "bench.json")
    bench = json.loads((w / "bench.json").read_text())
    assert {"ours-9d", "vqf-9d", "fusion-9d", "madgwick-9d", "mahony-9d"} <= set(bench["methods"])


API_SCRIPT = r'''
import sys
import numpy as np
import attekf
from attekf.io import read_recording

rec = read_recording(sys.argv[1])
out = {}
for scalar in ("float", "double", "fixed"):
    f = attekf.Filter(scalar=scalar)
    dt = np.diff(rec.t)
    dt = np.concatenate((dt[:1], dt))  # the first step as attekf.estimate takes it
    est = [f.update(g, a, m, dt=d) for g, a, m, d in zip(rec.gyr, rec.acc, rec.mag, dt)]
    out[f"{scalar}_update_quat"] = np.array([e.quaternion for e in est])
    out[f"{scalar}_update_sigma"] = np.array([e.sigma for e in est])
    out[f"{scalar}_update_flags"] = np.array([int(e.flags) for e in est])
    res = attekf.estimate(rec.gyr, rec.acc, rec.mag, t=rec.t, scalar=scalar)
    out[f"{scalar}_batch_quat"] = res.quat
    out[f"{scalar}_batch_state"] = res.state
    out[f"{scalar}_batch_var"] = res.var
    out[f"{scalar}_batch_flags"] = res.flags
    out[f"{scalar}_batch_status"] = res.status
np.savez(sys.argv[2], **out)
'''


def test_filter_and_batch_api_agree_with_the_source_tree_bit_for_bit(installed):
    w = installed.work
    if not (w / "rec.csv").exists():
        installed.run(installed.bin / "attekf", "sim", "-q", "rec.csv", "--duration", "20", "--seed", "5")
    script = w / "api.py"
    script.write_text(API_SCRIPT)
    installed.run(installed.python, script, "rec.csv", "api_pkg.npz")
    _run([REPO / ".venv" / "bin" / "python", script, "rec.csv", "api_tree.npz"], w, _clean_env())
    pkg, tree = np.load(w / "api_pkg.npz"), np.load(w / "api_tree.npz")
    assert set(pkg.files) == set(tree.files)
    for key in pkg.files:
        np.testing.assert_array_equal(pkg[key], tree[key], err_msg=key)
    # the per-sample API and the one-call batch run the same filter on the same time steps
    for scalar in ("float", "double", "fixed"):
        np.testing.assert_array_equal(pkg[f"{scalar}_update_quat"], pkg[f"{scalar}_batch_quat"])
