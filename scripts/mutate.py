#!/usr/bin/env python3
"""Mutation testing of the estimator core (docs/reliability.md, "Mutation testing").

Each mutant of tests/mutation/mutants.toml (one small textual edit of the core, the generated
kernels or the fixed-point code) is built in a scratch copy of the tree, never in the working
tree, and run against a fast subset of the tests, fastest first, until one fails:

  1. ctest, label `unit` (every C test of the host build; the drift check of the generated
     code, codegen_current, is not among them, so a mutant of a generated file must be killed
     by behaviour); only the scalar builds the mutated file is compiled into;
  2. pytest, the files that run the estimator (PYTEST_FILES), CI=true so that missing data
     fails rather than skips;
  3. a short run of the fuzz targets fuzz_att_f / fuzz_att_x from the committed seeds.

A mutant is killed by a failing test (or a time-out); it survives if all pass. A mutant whose
anchor does not occur exactly once is stale: the script fails before it builds anything. A
mutant that does not compile fails the script too (mutants must be realistic code). So does a
survivor the mutant file does not mark `accepted` (docs/reliability.md lists them), so that a
lost test shows.

    scripts/mutate.py                       # every mutant, 2 workers
    scripts/mutate.py --list                # the mutants, with stale anchors marked
    scripts/mutate.py --only accel_relinearisation_sign,bias_remap_wrong_row
    scripts/mutate.py --jobs 1 --fuzz-time 10 --scratch /tmp/mut

Scratch trees (build/mutate/w<k>/ by default) are kept between runs: a re-run syncs the
changed files only and rebuilds incrementally. Python standard library only; the tests use the
project's virtual environment (.venv).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

ROOT = Path(__file__).resolve().parents[1]
MUTANTS = ROOT / "tests" / "mutation" / "mutants.toml"
# pytest files that run the estimator (the C code through the extension modules)
PYTEST_FILES = (
    "tests/python/test_filter.py",
    "tests/python/test_filter_outputs.py",
    "tests/python/test_filter_state.py",
    "tests/python/test_native.py",
    "tests/python/test_rest.py",
    "tests/python/test_scenarios.py",
    "tests/python/test_consistency_bounds.py",
    "tests/python/test_broad_regression.py",
)
FUZZ_TARGETS = {"f": "fuzz_att_f", "x": "fuzz_att_x"}
NAME_RE = re.compile(r"^[a-z0-9_]+$")
SCALARS = ("f", "d", "x")


def log(msg: str) -> None:
    print(f"[mutate] {msg}", flush=True)


# ---------------------------------------------------------------------------------------------
# The mutants
# ---------------------------------------------------------------------------------------------
@dataclass
class Mutant:
    name: str
    file: str
    anchor: str
    replace: str
    why: str
    accepted: str = ""
    stale: str = ""          # why the anchor does not apply ('' if it does)


def load_mutants(path: Path) -> List[Mutant]:
    """The mutants of the file, each checked against the working tree (Mutant.stale)."""
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise SystemExit(f"{path}: {e}")
    out: List[Mutant] = []
    seen = set()
    for k, row in enumerate(data.get("mutant", []), 1):
        missing = [f for f in ("name", "file", "anchor", "replace", "why") if not isinstance(row.get(f), str)]
        if missing:
            raise SystemExit(f"{path}: mutant {k}: missing or not a string: {', '.join(missing)}")
        unknown = set(row) - {"name", "file", "anchor", "replace", "why", "accepted"}
        if unknown:
            raise SystemExit(f"{path}: mutant {row['name']}: unknown field(s) {', '.join(sorted(unknown))}")
        if not NAME_RE.match(row["name"]) or row["name"] in seen:
            raise SystemExit(f"{path}: mutant {k}: name {row['name']!r} not [a-z0-9_]+ or given twice")
        seen.add(row["name"])
        m = Mutant(row["name"], row["file"], row["anchor"], row["replace"], row["why"], row.get("accepted", ""))
        src = ROOT / m.file
        if not src.is_file():
            m.stale = f"{m.file}: no such file"
        elif m.anchor == m.replace:
            m.stale = "replace equals anchor"
        else:
            n = src.read_text().count(m.anchor)
            if n != 1:
                m.stale = f"anchor occurs {n} times in {m.file} (must be exactly once)"
        out.append(m)
    if len(out) == 0:
        raise SystemExit(f"{path}: no [[mutant]] entries")
    return out


def scalars_of(rel: str) -> Tuple[str, ...]:
    """The scalar builds a source file is compiled into (firmware/CMakeLists.txt's lists of
    the float/double-only and fixed-point-only sources); headers and the rest: all three."""
    text = (ROOT / "firmware" / "CMakeLists.txt").read_text()
    for var, scal in (("ATTEKF_IEEE_SOURCES", ("f", "d")), ("ATTEKF_FIXED_SOURCES", ("x",))):
        m = re.search(r"set\(" + var + r"\b(.*?)CACHE", text, re.S)
        if m and any(p.endswith("/" + rel.removeprefix("firmware/")) for p in m.group(1).split()):
            return scal
    return SCALARS


def test_scalars(name: str) -> Tuple[str, ...]:
    """The scalar builds a ctest test runs (its name's _f/_d/_x part; none: any)."""
    return tuple(t for t in name.split("_") if t in SCALARS)


# ---------------------------------------------------------------------------------------------
# Scratch trees
# ---------------------------------------------------------------------------------------------
def tracked_files() -> List[str]:
    """The working tree's files (tracked and untracked, not ignored): what a scratch tree holds."""
    out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                         capture_output=True, check=True).stdout.decode()
    return sorted(p for p in set(out.split("\0")) if p and (ROOT / p).is_file())


def sync_tree(dst: Path, files: Sequence[str]) -> int:
    """Makes dst a copy of the listed files (only changed ones are written, so a build there
    stays incremental); removes the files a previous sync copied that are gone. Returns the
    number written."""
    manifest = dst / ".mutate-files"
    old = set(manifest.read_text().split("\n")) if manifest.is_file() else set()
    written = 0
    for rel in files:
        src, out = ROOT / rel, dst / rel
        data = src.read_bytes()
        if not out.is_file() or out.read_bytes() != data:
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_bytes(data)
            shutil.copymode(src, out)
            written += 1
    for rel in old - set(files):
        if rel and (dst / rel).is_file():
            (dst / rel).unlink()
    manifest.write_text("\n".join(files))
    return written


def tree_hash(tree: Path, files: Sequence[str]) -> str:
    h = hashlib.sha256()
    for rel in files:
        h.update(rel.encode() + b"\0" + (tree / rel).read_bytes() + b"\0")
    return h.hexdigest()[:16]


def run(cmd: Sequence[str], cwd: Path, env: Dict[str, str], timeout: float) -> Tuple[int, str, float]:
    """(exit status, output, seconds); a time-out is status -9 with what was printed."""
    t0 = time.monotonic()
    p = subprocess.Popen(list(cmd), cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         start_new_session=True)
    try:
        out, _ = p.communicate(timeout=timeout)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, 9)
        out, _ = p.communicate()
        rc = -9
    return rc, out.decode(errors="replace"), time.monotonic() - t0


@dataclass
class TestCase:
    kind: str                 # ctest, pytest, fuzz
    name: str
    scalars: Tuple[str, ...]  # () = runs for any mutated file
    seconds: float = 0.0      # in the baseline
    deselect: List[str] = field(default_factory=list)  # pytest ids failing in the baseline (--allow-baseline-failures)


class Worker:
    """One scratch tree with its host and fuzz builds."""

    def __init__(self, base: Path, k: int, fuzz_time: float):
        self.tree = base / f"w{k}"
        self.host = self.tree / "build" / "host"
        self.fuzz = self.tree / "build" / "fuzz"
        self.fuzz_time = fuzz_time
        self.env = test_env(base, self.tree)
        self.fuzz_built = False

    def sync(self, files: Sequence[str]) -> int:
        self.tree.mkdir(parents=True, exist_ok=True)
        return sync_tree(self.tree, files)

    def build_host(self) -> Tuple[bool, str]:
        if not (self.host / "build.ninja").is_file():
            unity = ROOT / "build" / "host" / "_deps" / "unity-2.6.1"
            cmd = ["cmake", "-S", str(self.tree), "-B", str(self.host), "-G", "Ninja",
                   "-DCMAKE_BUILD_TYPE=RelWithDebInfo", f"-DPython3_EXECUTABLE={venv_python()}"]
            if (unity / "unity.c").is_file():
                cmd.append(f"-DUNITY_DIR={unity}")
            rc, out, _ = run(cmd, self.tree, self.env, 900)
            if rc != 0:
                return False, out
        rc, out, _ = run(["cmake", "--build", str(self.host)], self.tree, self.env, 3600)
        return rc == 0, out

    def build_fuzz(self) -> Tuple[bool, str]:
        if not (self.fuzz / "build.ninja").is_file():
            rc, out, _ = run(["cmake", "-S", str(self.tree / "tests" / "fuzz"), "-B", str(self.fuzz), "-G", "Ninja",
                              "-DCMAKE_C_COMPILER=clang"], self.tree, self.env, 900)
            if rc != 0:
                return False, out
        rc, out, _ = run(["cmake", "--build", str(self.fuzz), "--target", *FUZZ_TARGETS.values()], self.tree,
                         self.env, 3600)
        self.fuzz_built = rc == 0
        return rc == 0, out

    # -- the tests ------------------------------------------------------------------------
    def ctest_names(self) -> List[str]:
        rc, out, _ = run(["ctest", "--test-dir", str(self.host), "-N", "-L", "unit", "--show-only=json-v1"],
                         self.tree, self.env, 120)
        if rc != 0:
            raise SystemExit(f"ctest -N failed:\n{out}")
        return [t["name"] for t in json.loads(out[out.index("{"):])["tests"] if t["name"] != "codegen_current"]

    def run_test(self, t: TestCase, timeout: float, stop: bool = True) -> Tuple[bool, str, float]:
        """(passed, the failure's first lines, seconds). stop=False (the baseline): pytest runs
        every test of its file and records the failing ones in t.deselect."""
        if t.kind == "ctest":
            rc, out, sec = run(["ctest", "--test-dir", str(self.host), "-R", f"^{re.escape(t.name)}$",
                                "--output-on-failure", "--timeout", str(int(timeout))],
                               self.tree, self.env, timeout + 60)
            if rc == 0 and re.search(r"100% tests passed", out) and "Not Run" not in out:
                return True, "", sec
            return False, failure_lines(out, rc, self.tree), sec
        if t.kind == "pytest":
            # one process for every file (the interpreter and numpy start once), in their order
            opts = ["-x"] if stop else []
            rc, out, sec = run([venv_python(), "-m", "pytest", *t.name.split(), *opts, "-q", "-rfE", "-p",
                                "no:cacheprovider", *[f"--deselect={d}" for d in t.deselect]], self.tree, self.env,
                               timeout)
            if not stop:
                t.deselect = t.deselect + re.findall(r"^(?:FAILED|ERROR) (\S+)", out, re.M)
            if rc == 0:
                return True, "", sec
            return False, failure_lines(out, rc, self.tree), sec
        # fuzz
        if not self.fuzz_built:
            ok, out = self.build_fuzz()
            if not ok:
                return False, "fuzz build failed: " + out[-400:], 0.0
        work = self.tree / "build" / "mutate-fuzz" / t.name
        shutil.rmtree(work, ignore_errors=True)
        (work / "corpus").mkdir(parents=True)
        seeds = self.tree / "tests" / "fuzz" / "corpus" / "fuzz_att"
        rc, out, sec = run([str(self.fuzz / t.name), f"-max_total_time={int(self.fuzz_time)}", "-seed=1",
                            "-timeout=10", "-rss_limit_mb=2048", f"-artifact_prefix={work}/",
                            str(work / "corpus"), str(seeds)], work, self.env, self.fuzz_time + 120)
        if rc == 0:
            return True, "", sec
        return False, failure_lines(out, rc, self.tree), sec


def failure_lines(out: str, rc: int, tree: Path) -> str:
    """The line that says why a test failed (Unity, pytest, an invariant, a sanitizer)."""
    if rc == -9:
        return "time-out"
    pats = (r"^FAILED .*", r".*:FAIL:.*", r"^invariant failed.*", r".*runtime error:.*", r"^E +.*",
            r".*ERROR: AddressSanitizer.*", r".*result=FAIL.*", r".*FAIL.*")
    for pat in pats:
        m = re.search(pat, out, re.M)
        if m:
            return m.group(0).strip().replace(str(tree) + "/", "")[:240]
    return (out.strip().splitlines() or ["(no output)"])[-1][:240]


def venv_python() -> str:
    p = ROOT / ".venv" / "bin" / "python"
    return str(p) if p.is_file() else sys.executable


def test_env(base: Path, tree: Path) -> Dict[str, str]:
    """The environment of every command in a scratch tree: Python imports the scratch tree's
    attekf (not the working tree's editable install, whose finder sitecustomize removes), so
    the extension modules and programs are the mutant's; the BROAD data of the working tree;
    CI=true: a missing prerequisite fails instead of skipping."""
    site = base / "pysite"
    site.mkdir(parents=True, exist_ok=True)
    (site / "sitecustomize.py").write_text(
        "# written by scripts/mutate.py: the scratch tree's attekf, not the editable install's\n"
        "import sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'ScikitBuild' not in type(f).__name__]\n")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(tree / "host_tools")])
    env["CI"] = "true"
    env.setdefault("ATTEKF_BROAD_DIR", str(ROOT.parent / "shared" / "data" / "broad"))
    env.pop("ATTEKF_LIB", None)
    env["ASAN_OPTIONS"] = "detect_leaks=0"
    return env


# ---------------------------------------------------------------------------------------------
# The campaign
# ---------------------------------------------------------------------------------------------
@dataclass
class Result:
    name: str
    status: str = ""          # killed, survived, invalid
    killer: str = ""
    detail: str = ""
    seconds: float = 0.0
    tests_run: int = 0


def baseline(w: Worker, files: Sequence[str], base: Path, allow_failures: bool) -> List[TestCase]:
    """Every test of the subset on the unmutated tree, with its time (cached per tree
    content). Fails the script if one fails: the mutants would mean nothing. With
    allow_failures, a failing pytest test is left out (deselected) and said so instead."""
    cache = base / "baseline.json"
    key = tree_hash(w.tree, files) + f"/fuzz{w.fuzz_time:g}"
    if cache.is_file():
        data = json.loads(cache.read_text())
        if data.get("key") == key:
            return [TestCase(**t) for t in data["tests"]]
    tests = [TestCase("ctest", n, test_scalars(n)) for n in w.ctest_names()]
    tests.append(TestCase("pytest", " ".join(f for f in PYTEST_FILES if (w.tree / f).is_file()), ()))
    tests += [TestCase("fuzz", t, (s,)) for s, t in FUZZ_TARGETS.items()]
    ok, out = w.build_fuzz()
    if not ok:
        raise SystemExit(f"fuzz build failed in {w.tree}:\n{out[-2000:]}")
    log(f"baseline: {len(tests)} tests on the unmutated tree")
    failed = []
    for t in tests:
        passed, why, sec = w.run_test(t, 1800, stop=False)
        t.seconds = round(sec, 2)
        if not passed and not (allow_failures and t.deselect):
            failed.append(f"{t.kind} {t.name}: {why}")
    if failed:
        raise SystemExit("the unmutated tree fails its tests (fix that first):\n  " + "\n  ".join(failed))
    if any(t.deselect for t in tests) and allow_failures:
        # the baseline again without them: the times, and that the rest passes
        for t in tests:
            if t.deselect:
                passed, why, sec = w.run_test(t, 1800)
                t.seconds = round(sec, 2)
                if not passed:
                    raise SystemExit(f"{t.name} fails without its failing tests too: {why}")
    cache.write_text(json.dumps({"key": key, "tests": [t.__dict__ for t in tests]}, indent=1))
    return tests


def order(tests: Sequence[TestCase], hint: str) -> List[TestCase]:
    """Fastest first within each kind (ctest, pytest, fuzz), the test that killed this
    mutant last time before all."""
    rank = {"ctest": 0, "pytest": 1, "fuzz": 2}
    out = sorted(tests, key=lambda t: (rank[t.kind], t.seconds))
    first = [t for t in out if f"{t.kind} {t.name}" == hint]
    return first + [t for t in out if t not in first]


def run_mutant(w: Worker, m: Mutant, tests: Sequence[TestCase], hint: str, all_tests: bool) -> Result:
    r = Result(m.name)
    t0 = time.monotonic()
    path = w.tree / m.file
    original = path.read_text()
    if original.count(m.anchor) != 1:
        r.status, r.detail = "invalid", "anchor not found once in the scratch tree"
        return r
    path.write_text(original.replace(m.anchor, m.replace, 1))
    w.fuzz_built = False
    try:
        ok, out = w.build_host()
        if not ok:
            r.status, r.detail = "invalid", "does not build: " + next(
                (ln for ln in out.splitlines() if "error" in ln), out[-300:])[:300]
            return r
        scal = scalars_of(m.file)
        for t in order(tests, hint):
            if t.scalars and not set(t.scalars) & set(scal):
                continue
            passed, why, _ = w.run_test(t, max(60.0, 6.0 * t.seconds))
            r.tests_run += 1
            if not passed:
                if not r.killer:
                    r.status, r.killer, r.detail = "killed", f"{t.kind} {t.name}", why
                if not all_tests:
                    break
        if not r.status:
            r.status = "survived"
    finally:
        path.write_text(original)
        r.seconds = time.monotonic() - t0
    return r


def print_table(mutants: Sequence[Mutant], results: Dict[str, Result]) -> None:
    w = max(len(m.name) for m in mutants)
    print(f"\n{'mutant':<{w}}  {'file':<36} {'result':<9} {'s':>5}  killed by / note")
    for m in mutants:
        r = results.get(m.name)
        if r is None:
            continue
        note = f"{r.killer}: {r.detail}" if r.status == "killed" else (m.accepted or r.detail)
        print(f"{m.name:<{w}}  {m.file.removeprefix('firmware/'):<36} {r.status:<9} {r.seconds:5.0f}  {note[:150]}")


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="The mutants: tests/mutation/mutants.toml. Results: docs/reliability.md.")
    ap.add_argument("--list", action="store_true", help="list the mutants (stale anchors marked) and exit")
    ap.add_argument("--only", metavar="NAME[,NAME...]", help="run these mutants only")
    ap.add_argument("--jobs", type=int, default=2, help="scratch trees working in parallel (default 2)")
    ap.add_argument("--fuzz-time", type=float, default=20.0, help="seconds per fuzz target and mutant (default 20)")
    ap.add_argument("--scratch", type=Path, default=ROOT / "build" / "mutate",
                    help="where the scratch trees live (default build/mutate)")
    ap.add_argument("--all-tests", action="store_true", help="run every test of a mutant, not only until one fails")
    ap.add_argument("--json", type=Path, help="write the results to this file")
    ap.add_argument("--allow-baseline-failures", action="store_true",
                    help="leave out the pytest tests that fail on the unmutated tree (said so; exit status 1) "
                         "instead of stopping")
    args = ap.parse_args(argv)

    mutants = load_mutants(MUTANTS)
    stale = [m for m in mutants if m.stale]
    if args.list:
        for m in mutants:
            mark = f"STALE: {m.stale}" if m.stale else ("accepted" if m.accepted else "")
            print(f"{m.name:<40} {m.file:<40} {mark}\n    {m.why}")
        print(f"{len(mutants)} mutants, {len(stale)} stale")
        return 1 if stale else 0
    if stale:
        for m in stale:
            print(f"[mutate] stale mutant {m.name}: {m.stale}", file=sys.stderr)
        print(f"[mutate] {len(stale)} stale mutant(s): re-anchor them in {MUTANTS.relative_to(ROOT)}", file=sys.stderr)
        return 1
    if args.only:
        names = [n.strip() for n in args.only.split(",") if n.strip()]
        unknown = [n for n in names if n not in {m.name for m in mutants}]
        if unknown:
            print(f"[mutate] --only: unknown mutant(s): {', '.join(unknown)}", file=sys.stderr)
            return 2
        mutants = [m for m in mutants if m.name in names]
    if args.jobs < 1 or args.fuzz_time <= 0:
        print("[mutate] --jobs must be >= 1 and --fuzz-time > 0", file=sys.stderr)
        return 2
    jobs = min(args.jobs, len(mutants))
    base = args.scratch.resolve()
    base.mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()
    files = tracked_files()
    workers = [Worker(base, k, args.fuzz_time) for k in range(jobs)]

    def prepare(w: Worker) -> None:
        n = w.sync(files)
        ok, out = w.build_host()
        if not ok:
            raise SystemExit(f"the unmutated tree does not build in {w.tree}:\n{out[-3000:]}")
        log(f"{w.tree.name}: {n} files synced, built")

    log(f"{len(mutants)} mutants, {jobs} scratch tree(s) under {base}")
    with cf.ThreadPoolExecutor(jobs) as ex:
        list(ex.map(prepare, workers))
    tests = baseline(workers[0], files, base, args.allow_baseline_failures)
    log(f"baseline passed: {len(tests)} tests, {sum(t.seconds for t in tests):.0f} s in all")
    excluded = [d for t in tests for d in t.deselect]
    for d in excluded:
        log(f"WARNING: fails on the unmutated tree, left out: {d}")

    hints_file = base / "killers.json"
    hints = json.loads(hints_file.read_text()) if hints_file.is_file() else {}
    results: Dict[str, Result] = {}
    lock = threading.Lock()
    queue = list(mutants)

    def work(w: Worker) -> None:
        while True:
            with lock:
                if not queue:
                    return
                m = queue.pop(0)
            r = run_mutant(w, m, tests, hints.get(m.name, ""), args.all_tests)
            with lock:
                results[m.name] = r
                done = len(results)
                log(f"[{done}/{len(mutants)}] {m.name}: {r.status} ({r.seconds:.0f} s"
                    + (f", {r.killer}" if r.killer else "") + ")")

    with cf.ThreadPoolExecutor(jobs) as ex:
        list(ex.map(work, workers))
    for r in results.values():
        if r.status == "killed":
            hints[r.name] = r.killer
    hints_file.write_text(json.dumps(hints, indent=1, sort_keys=True))

    print_table(mutants, results)
    killed = sum(r.status == "killed" for r in results.values())
    survived = [m for m in mutants if results[m.name].status == "survived"]
    invalid = [m for m in mutants if results[m.name].status == "invalid"]
    unexpected = [m for m in survived if not m.accepted]
    stale_notes = [m for m in mutants if m.accepted and results[m.name].status == "killed"]
    counted = killed + len(survived)
    rate = 100.0 * killed / counted if counted else 0.0
    wall = time.monotonic() - t_start
    print(f"\nkilled {killed} of {counted} mutants: kill rate {rate:.1f} % "
          f"({len(survived)} survived, {len(unexpected)} of them not marked accepted; {len(invalid)} invalid); "
          f"wall time {wall / 60:.1f} min with {jobs} job(s)")
    for m in stale_notes:
        print(f"[mutate] note: {m.name} is marked accepted but was killed: remove its 'accepted'")
    if args.json:
        args.json.write_text(json.dumps({"kill_rate_pct": rate, "wall_s": wall, "jobs": jobs,
                                         "results": [results[m.name].__dict__ for m in mutants]}, indent=1))
    if excluded:
        print("[mutate] FAILED: tests that fail on the unmutated tree were left out: " + ", ".join(excluded),
              file=sys.stderr)
        return 1
    if invalid:
        print("[mutate] FAILED: mutants that do not build: " + ", ".join(m.name for m in invalid), file=sys.stderr)
        return 1
    if unexpected:
        print("[mutate] FAILED: survivors not marked accepted (add a test, or the reason to the mutant and "
              "to docs/reliability.md): " + ", ".join(m.name for m in unexpected), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
