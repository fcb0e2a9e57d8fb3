"""The Python package as a user gets it: a platform wheel, installed into a fresh virtual
environment outside the repository on a machine without a C compiler.

One sdist is built from host_tools/ (scikit-build-core, pinned in requirements.lock), pip turns
it into a wheel (CMake compiles the float, double and fixed-point extension modules; the wheel
is kept under build/package-test/, keyed by the sdist's SHA-256, so an unchanged sdist is not
rebuilt). A new virtual environment in a temporary directory, whose PATH has no C compiler
(cc, gcc, clang, ... left out; CC=false), installs the wheel with binary packages only
(--only-binary :all:, versions pinned by requirements.lock as constraints, their wheels kept in
build/package-test/wheelhouse and fetched from the registry when one is missing): first with
numpy alone, where the filter must run and every command must name the extra it needs, then
with the bench and can extras, where every command and the API run from a working directory outside
the repository with no ATTEKF_* variables, and the results must equal those of the source
tree's build (build/host) bit for bit.

Run by scripts/test.sh as its own step.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tarfile
import venv
import zipfile
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
HOST_TOOLS = REPO / "host_tools"
CACHE = REPO / "build" / "package-test"
LOCK = HOST_TOOLS / "requirements.lock"
# what compiles or links C: none of these may be on the installed environment's PATH
COMPILERS = re.compile(r"^(cc|c89|c99|c\+\+|cpp|gcc|g\+\+|clang|clang\+\+|tcc|icc|ld|as)([-.].*)?$|.*-(gcc|g\+\+|cc|ld|as)(-[0-9.]+)?$")


def _clean_env(extra_path: Path | None = None) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("ATTEKF_") and k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    if extra_path is not None:
        env["PATH"] = f"{extra_path}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    return env


def _run(cmd, cwd: Path, env: dict, timeout: float = 900) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
    if proc.returncode != 0:
        pytest.fail(f"{' '.join(str(c) for c in cmd)} exited {proc.returncode}\n"
                    f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}", pytrace=False)
    return proc


def _no_compiler_path(root: Path) -> Path:
    """A directory of links to the system's programs (/usr/bin, /bin) without any compiler,
    assembler or linker."""
    d = root / "bin-without-compiler"
    d.mkdir()
    for src in (Path("/usr/bin"), Path("/bin")):
        for p in sorted(src.iterdir()) if src.is_dir() else []:
            if COMPILERS.match(p.name) or (d / p.name).exists() or not os.access(p, os.X_OK):
                continue
            (d / p.name).symlink_to(p.resolve())
    return d


class Installed:
    def __init__(self, root: Path, wheel: Path):
        self.root = root
        self.wheel = wheel
        self.venv = root / "venv"
        self.bin = self.venv / "bin"
        self.python = self.bin / "python"
        self.work = root / "work"
        self.env = _clean_env()
        self.env["PATH"] = f"{self.bin}{os.pathsep}{_no_compiler_path(root)}"
        self.env.update(CC="false", CXX="false")

    def run(self, *args, **kw) -> subprocess.CompletedProcess:
        return _run(args, self.work, kw.pop("env", self.env), **kw)

    def pip_install(self, *reqs) -> None:
        """Installs wheels only (nothing to compile), from the wheelhouse, filled from the
        registry when a wheel is missing."""
        pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
        house = CACHE / "wheelhouse"
        house.mkdir(parents=True, exist_ok=True)
        req = [*reqs, "-c", LOCK]
        install = pip + ["--python", self.python, "install", "--only-binary", ":all:", "--no-index",
                         "--find-links", house, "--find-links", self.wheel.parent] + req
        proc = subprocess.run([str(c) for c in install], cwd=self.work, env=self.env, capture_output=True,
                              text=True, timeout=600)
        if proc.returncode != 0:
            _run(pip + ["download", "--only-binary", ":all:", "-d", house, "--find-links", self.wheel.parent]
                 + req, self.work, _clean_env())
            for w in house.glob("attekf-*"):     # only the dependencies are kept there
                w.unlink()
            _run(install, self.work, self.env)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(sdist, wheel) of host_tools/."""
    root = tmp_path_factory.mktemp("attekf-build")
    assert REPO not in root.parents, "the test environment must be outside the repository"
    dist = root / "dist"
    _run([sys.executable, "-c", "import sys, scikit_build_core.build as b; b.build_sdist(sys.argv[1])", dist],
         HOST_TOOLS, _clean_env())
    (sdist,) = dist.glob("attekf-*.tar.gz")
    digest = hashlib.sha256(sdist.read_bytes()).hexdigest()[:16]
    wheels = CACHE / digest
    if not list(wheels.glob("attekf-*.whl")):
        for old in CACHE.glob("[0-9a-f]" * 16):   # wheels of earlier sdists
            shutil.rmtree(old, ignore_errors=True)
        # an isolated build: scikit-build-core and numpy from the registry, then CMake
        _run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", "wheel", "--no-deps",
              "-w", root / "wheel", sdist], root, _clean_env())
        wheels.mkdir(parents=True)
        for w in (root / "wheel").glob("attekf-*.whl"):
            shutil.copy2(w, wheels)
    (wheel,) = wheels.glob("attekf-*.whl")
    return sdist, wheel


@pytest.fixture(scope="module")
def installed(built, tmp_path_factory) -> Installed:
    """A fresh environment with the wheel and numpy only, no compiler on its PATH."""
    inst = Installed(tmp_path_factory.mktemp("attekf-package"), built[1])
    inst.work.mkdir()
    # A virtual environment of its own; the source tree's pip installs into it (--python),
    # which saves bootstrapping a pip into every new environment.
    venv.EnvBuilder(with_pip=False).create(inst.venv)
    for name in ("cc", "gcc", "clang", "c99", "tcc", "ld"):
        assert shutil.which(name, path=inst.env["PATH"]) is None, f"{name} is on the test's PATH"
    inst.pip_install(str(inst.wheel))
    return inst


@pytest.fixture(scope="module")
def with_extras(installed) -> Installed:
    installed.pip_install("attekf[bench,can]")
    return installed


def test_sdist_carries_the_c_sources_and_nothing_of_the_build(built):
    with tarfile.open(built[0]) as tar:
        names = tar.getnames()
    top = names[0].split("/")[0]
    rel = {n[len(top) + 1:] for n in names}
    for needed in ("pyproject.toml", "CMakeLists.txt", "README.md", "native/core_filter.c", "attekf/filter.py",
                   "csrc/CMakeLists.txt", "csrc/firmware/CMakeLists.txt", "csrc/firmware/att/att.c",
                   "csrc/firmware/ekf/ekf.c", "csrc/firmware/app/dbc/attekf.dbc", "csrc/cmake/Warnings.cmake"):
        assert needed in rel, f"sdist lacks {needed}"
    assert not [n for n in rel if "__pycache__" in n or ".egg-info" in n or n.startswith(("build/", "csrc/build"))]
    assert "requirements.lock" not in rel


def test_the_wheel_is_a_platform_wheel_with_everything_and_no_codegen(built):
    wheel = built[1]
    tag = wheel.name.split("-", 2)[2]
    assert re.match(r"cp3\d+-cp3\d+-linux_\w+\.whl$", tag), tag      # this interpreter, this platform
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        meta = z.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
        entry = z.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
    for scalar in "fdx":
        assert [n for n in names if re.match(rf"attekf/_core_{scalar}\.cpython-.*\.so$", n)], scalar
    assert "attekf/data/attekf.dbc" in names and "attekf/filter.py" in names
    assert not [n for n in names if n.startswith("attekf/codegen")]
    assert "attekf = attekf.cli:main" in entry and "codegen" not in entry
    requires = [ln.split(":", 1)[1].strip() for ln in meta.splitlines() if ln.startswith("Requires-Dist:")]
    assert [r for r in requires if "extra ==" not in r] == ["numpy>=1.23"]
    for extra in ("tools", "can", "plots", "bench", "test"):
        assert f"Provides-Extra: {extra}" in meta
    assert re.search(r"^Summary: Attitude EKF", meta, re.M) and "Classifier: Programming Language :: C" in meta
    assert "Description-Content-Type: text/markdown" in meta and "import attekf" in meta


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
    out[f"{scalar}_state"] = np.frombuffer(f.get_state()["c_state"], np.uint8)
np.savez(sys.argv[2], **out)
'''

NUMPY_ONLY_SCRIPT = r'''
import copy, pickle, sys
import numpy as np
import attekf
for m in ("tqdm", "h5py", "matplotlib", "can", "cantools"):
    try:
        __import__(m)
        sys.exit(f"{m} is installed: the environment is not numpy-only")
    except ImportError:
        pass
rng = np.random.default_rng(1)
n = 2000
gyr = rng.normal(0, 0.05, (n, 3))
acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.05, (n, 3))
mag = np.tile([0.0, 20.0, -40.0], (n, 1)) + rng.normal(0, 0.3, (n, 3))
res = attekf.estimate(gyr, acc, mag, rate_hz=100.0, with_6d=True)
f = attekf.Filter(dt=0.01)
est = [f.update(g, a, m) for g, a, m in zip(gyr, acc, mag)]
assert np.array_equal(np.array([e.quaternion for e in est]), res.quat, equal_nan=True)
g = pickle.loads(pickle.dumps(f))
assert g.get_state() == f.get_state() and copy.deepcopy(f).settings == f.settings
print(res.aligned.sum(), res.six_d.aligned.sum(), attekf.__file__)
'''


def test_the_filter_runs_with_numpy_alone_and_no_compiler(installed):
    (installed.work / "numpy_only.py").write_text(NUMPY_ONLY_SCRIPT)
    out = installed.run(installed.python, "numpy_only.py").stdout.split()
    assert out[:2] == ["1991", "1991"] and installed.venv.resolve() in Path(out[2]).resolve().parents


@pytest.mark.parametrize("args, extra", [(["sim", "x.csv"], "tools"), (["run", "x.csv", "-o", "y.csv"], "tools"),
                                         (["replay", "x.csv", "--to-log", "y.log"], "can"),
                                         (["bench", "--data", "."], "bench")])
def test_without_extras_each_command_names_the_one_it_needs(installed, args, extra):
    proc = subprocess.run([str(installed.bin / "attekf"), *args], cwd=installed.work, env=installed.env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip() == (f"attekf {args[0]}: error: the Python package tqdm is needed for "
                                   f"attekf {args[0]}: pip install 'attekf[{extra}]'")
    assert installed.run(installed.bin / "attekf", "--help").stdout.startswith("usage: attekf")


def test_installed_package_uses_its_own_modules_and_dbc(with_extras):
    inst = with_extras
    out = inst.run(inst.python, "-c",
                   "import attekf.native as n, attekf.canproto as c; print(n.load('float').path); "
                   "print(n.load('fixed').path); print(c.dbc_path())").stdout.split()
    site = inst.venv.resolve()
    for p in out:
        assert site in Path(p).resolve().parents, f"{p} is not inside the virtual environment"
    # the overrides still win
    env = dict(inst.env, ATTEKF_LIB=str(REPO / "build" / "host" / "host_tools" / "native"),
               ATTEKF_DBC=str(REPO / "firmware" / "app" / "dbc" / "attekf.dbc"))
    out = inst.run(inst.python, "-c",
                   "import attekf.native as n, attekf.canproto as c; print(n.load('double').path); "
                   "print(c.dbc_path())", env=env).stdout.split()
    assert Path(out[0]).parent == Path(env["ATTEKF_LIB"]) and Path(out[1]) == Path(env["ATTEKF_DBC"])


def test_every_command_works_outside_the_repository(with_extras):
    inst = with_extras
    attekf = inst.bin / "attekf"
    inst.run(attekf, "sim", "-q", "rec.csv", "--duration", "20", "--seed", "5")
    inst.run(attekf, "sim", "-q", "trials/trial01.hdf5", "--duration", "10", "--seed", "6")
    # eval: the same numbers, and the same output file byte for byte, as the source tree's build
    inst.run(attekf, "eval", "-q", "rec.csv", "--no-plot", "--out", "eval_pkg", "--save-output")
    _run([REPO / ".venv" / "bin" / "attekf", "eval", "-q", "rec.csv", "--no-plot", "--out", "eval_tree",
          "--save-output"], inst.work, _clean_env())
    w = inst.work
    assert (w / "eval_pkg" / "rec_output.csv").read_bytes() == (w / "eval_tree" / "rec_output.csv").read_bytes()
    pkg = json.loads((w / "eval_pkg" / "results.json").read_text())["trials"][0]
    tree = json.loads((w / "eval_tree" / "results.json").read_text())["trials"][0]
    for key in ("rmse_deg", "within_3sigma_pct", "counts", "estimator_summary"):
        assert pkg[key] == tree[key], key
    inst.run(attekf, "run", "-q", "trials/trial01.hdf5", "-o", "run.h5", "--frame", "NED")
    # replay -> CAN log -> record: the packaged DBC encodes and decodes the samples
    inst.run(attekf, "replay", "-q", "rec.csv", "--to-log", "frames.log")
    inst.run(attekf, "record", "-q", "--from-log", "frames.log", "--inputs-csv", "inputs.csv",
             "--stats", "stats.json")

    def data_rows(name):
        lines = [r for r in (w / name).read_text().splitlines() if r and not r.startswith("#")]
        return lines[1:]  # after the header (sim's CSV starts with "# key: value" lines)
    assert len(data_rows("inputs.csv")) == len(data_rows("rec.csv")) == 2001
    # bench with the [bench] extra: ours and every baseline on a simulated trial
    inst.run(attekf, "bench", "-q", "--data", "trials", "--jobs", "1", "--no-plot", "--json", "bench.json")
    bench = json.loads((w / "bench.json").read_text())
    assert {"ours-9d", "vqf-9d", "fusion-9d", "madgwick-9d", "mahony-9d"} <= set(bench["methods"])


def test_filter_and_batch_api_agree_with_the_source_tree_bit_for_bit(with_extras):
    inst = with_extras
    w = inst.work
    if not (w / "rec.csv").exists():
        inst.run(inst.bin / "attekf", "sim", "-q", "rec.csv", "--duration", "20", "--seed", "5")
    script = w / "api.py"
    script.write_text(API_SCRIPT)
    inst.run(inst.python, script, "rec.csv", "api_pkg.npz")
    _run([REPO / ".venv" / "bin" / "python", script, "rec.csv", "api_tree.npz"], w, _clean_env())
    pkg, tree = np.load(w / "api_pkg.npz"), np.load(w / "api_tree.npz")
    assert set(pkg.files) == set(tree.files)
    for key in pkg.files:
        np.testing.assert_array_equal(pkg[key], tree[key], err_msg=key)
    # the per-sample API and the one-call batch run the same filter on the same time steps
    for scalar in ("float", "double", "fixed"):
        np.testing.assert_array_equal(pkg[f"{scalar}_update_quat"], pkg[f"{scalar}_batch_quat"])
