"""The README's C example compiles as shown: its includes at file scope, its statements in a
function body (the sensor values as the function's parameters), with the project's warning set
as errors against the float build's headers. Compile only; a C compiler is needed (fails under
CI=true, skips elsewhere without one)."""

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
