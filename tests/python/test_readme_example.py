"""The README's C example compiles as shown: its includes at file scope, its statements in a
function body (the sensor values as the function's parameters), with the project's warning set
as errors against the float build's headers. Compile only; a C compiler is needed (fails under
CI=true, skips elsewhere without one). The Python examples of README.md and of the package's
own README (host_tools/README.md, what a pip user reads) run as shown."""

from __future__ import annotations

import re
import shutil
import subprocess

import prereq

REPO = prereq.REPO
WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
            "-Wdouble-promotion", "-Wcast-qual", "-Wstrict-prototypes", "-Wmissing-prototypes",
            "-Wundef", "-Wvla", "-Werror"]  # cmake/Warnings.cmake


def readme_example() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```c\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1, f"README.md: expected one C example, found {len(blocks)}"
    return blocks[0]


def test_readme_c_example_compiles(tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        prereq.unavailable("no C compiler (cc) on PATH")
    code = readme_example()
    lines = code.splitlines()
    includes = [ln for ln in lines if ln.startswith("#include")]
    body = [ln for ln in lines if not ln.startswith("#include")]
    assert includes and body
    params = ", ".join(f"float {v}" for v in ("gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz"))
    unit = "\n".join(includes + [
        f"void readme_example({params});",
        f"void readme_example({params})", "{",
        *("    " + ln for ln in body),
        "    (void)st;",
        "}", ""])
    src = tmp_path / "readme_example.c"
    src.write_text(unit, encoding="utf-8")
    p = subprocess.run([cc, *WARNINGS, "-DEKF_SCALAR_FLOAT=1", f"-I{REPO / 'firmware' / 'att'}",
                        f"-I{REPO / 'firmware' / 'ekf'}", "-c", str(src), "-o", str(tmp_path / "x.o")],
                       capture_output=True, text=True)
    assert p.returncode == 0, f"README.md's C example does not compile:\n{unit}\n{p.stderr}"


def test_readme_python_example_runs():
    """The README's Python example runs as shown on one sample (gyr, acc, mag) and on arrays
    of them (gyr_n, acc_n, mag_n), and gives an aligned, unit-quaternion estimate at rest."""
    import numpy as np

    text = (REPO / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1, f"README.md: expected one Python example, found {len(blocks)}"
    n = 200  # 2 s at 100 Hz, level and at rest: well past the 10 alignment samples
    gyr, acc, mag = np.zeros(3), np.array([0.0, 0.0, 9.81]), np.array([0.0, 20.0, -40.0])
    env = {"gyr": gyr, "acc": acc, "mag": mag, "gyr_n": np.tile(gyr, (n, 1)),
           "acc_n": np.tile(acc, (n, 1)), "mag_n": np.tile(mag, (n, 1))}
    exec(compile(blocks[0], "README.md (python example)", "exec"), env)
    # level, at rest, the field due north (body x east): roll, pitch, yaw 0 (measured exactly 0)
    np.testing.assert_allclose(env["res"].euler[-1], 0.0, atol=1e-6)
    np.testing.assert_allclose(env["res"].quat[-1], [1.0, 0.0, 0.0, 0.0], atol=1e-6)
    assert env["est"].quaternion.shape == (4,) and env["est"].status == "EKF_OK"


def test_package_readme_python_example_runs():
    """host_tools/README.md's Python example runs as shown on (N, 3) arrays gyr, acc, mag at
    100 Hz, and its outputs are what it says: an aligned estimate with its uncertainty, and 6D."""
    import numpy as np

    text = (REPO / "host_tools" / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1, f"host_tools/README.md: expected one Python example, found {len(blocks)}"
    n = 300
    rng = np.random.default_rng(0)
    env = {"gyr": rng.normal(0, 0.01, (n, 3)), "acc": np.tile([0.0, 0.0, 9.81], (n, 1)),
           "mag": np.tile([0.0, 20.0, -40.0], (n, 1))}
    exec(compile(blocks[0], "host_tools/README.md (python example)", "exec"), env)
    est, res = env["est"], env["res"]
    assert est.aligned and np.isfinite(est.quaternion).all() and est.covariance.shape == (3, 3)
    np.testing.assert_allclose(env["roll"], 0.0, atol=0.01)
    assert res.quat.shape == (n, 4) and res.six_d.quat.shape == (n, 4)
    np.testing.assert_array_equal(res.quat[-1], est.quaternion)   # the same filter both ways
