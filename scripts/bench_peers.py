"""The peers on the same boards: the side-by-side part of scripts/bench_firmware.py --peers.

Fusion (x-io, C) comes from the imufusion source distribution on PyPI, VQF and BasicVQF
(C++) from the vqf one. Both are downloaded at benchmark time with pip (the source
distribution itself: --no-binary for these two names; pip installs their build
dependencies to read the metadata), checked against the SHA-256 pinned here, and extracted
into the build tree (build/peers-src by default). Nothing of theirs is committed.

Then, per cross build, a private build tree (build/peers-<preset>) with -DATTEKF_PEERS_DIR
builds firmware/target/peers/ (their sources with the board's flags, our glue): the
instruction benchmark on bench.c's samples and a footprint image per peer; on the host
(build/peers-host, the host build's RelWithDebInfo flags) the same program runs under
callgrind, collecting only the measured updates (--toggle-collect=peers_measured_step).
"""
import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile

PEERS = ("Fusion", "BasicVQF", "VQF")
FOOTPRINT = {"Fusion": "fusion", "VQF": "vqf", "BasicVQF": "basicvqf"}

PINNED = {
    # name: (version, sha256 of the .tar.gz)
    "imufusion": ("1.3.3", "b2175e5ed1e1cca95ef8673432d1f089037f957cde4325a510738c9e7ad3b87d"),
    "vqf": ("2.1.2", "2bf7134ffb181d518ac8c0855a239881c5a3e06e927605c351e72bbce1623233"),
}


class PeerError(Exception):
    pass


def _sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 16), b""):
            h.update(block)
    return h.hexdigest()


def _extract(archive, dest):
    with tarfile.open(archive, "r:gz") as tar:
        for m in tar.getmembers():
            target = os.path.realpath(os.path.join(dest, m.name))
            if not target.startswith(os.path.realpath(dest) + os.sep) or m.issym() or m.islnk():
                raise PeerError(f"{archive}: unsafe member {m.name}")
        tar.extractall(dest)


def fetch(dest, log=print, python=sys.executable):
    """Makes dest/<name>-<version>/ for every pinned peer; returns dest."""
    os.makedirs(dest, exist_ok=True)
    for name, (version, sha) in PINNED.items():
        tree = os.path.join(dest, f"{name}-{version}")
        archive = os.path.join(dest, f"{name}-{version}.tar.gz")
        if os.path.isfile(archive) and _sha256(archive) == sha and os.path.isdir(tree):
            continue
        if not (os.path.isfile(archive) and _sha256(archive) == sha):
            log(f"downloading {name} {version} (source distribution) with pip")
            with tempfile.TemporaryDirectory(dir=dest) as tmp:
                r = subprocess.run([python, "-m", "pip", "download", "--no-deps", "--no-binary", name,
                                    "--disable-pip-version-check", "-q", "-d", tmp, f"{name}=={version}"],
                                   capture_output=True, text=True)
                got = os.path.join(tmp, f"{name}-{version}.tar.gz")
                if r.returncode != 0 or not os.path.isfile(got):
                    raise PeerError(f"pip download {name}=={version} failed:\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
                if _sha256(got) != sha:
                    raise PeerError(f"{name}-{version}.tar.gz: SHA-256 {_sha256(got)}, expected {sha}")
                shutil.move(got, archive)
        if os.path.isdir(tree):
            shutil.rmtree(tree)
        _extract(archive, dest)
        if not os.path.isdir(tree):
            raise PeerError(f"{archive}: no {name}-{version}/ inside")
    return dest


# ---- measurement ------------------------------------------------------------------------------
def _tree(bf, args, name):
    if args.build_root is not None:
        return os.path.join(args.build_root, f"peers-{name}-{args.build_type}")
    return os.path.join(bf.ROOT, "build", f"peers-{name}")


def _configure(bf, args, bdir, src, toolchain=None, build_type=None):
    if os.path.isfile(os.path.join(bdir, "build.ninja")):
        return
    bf.log(args, f"configuring {os.path.relpath(bdir, bf.ROOT)}")
    cmd = ["cmake", "-S", bf.ROOT, "-B", bdir, "-G", "Ninja", f"-DATTEKF_PEERS_DIR={src}",
           f"-DCMAKE_BUILD_TYPE={build_type or args.build_type}",
           f"-DPython3_EXECUTABLE={os.path.join(bf.ROOT, '.venv', 'bin', 'python')}"]
    if toolchain:
        cmd += ["--toolchain", os.path.join(bf.ROOT, "cmake", "toolchains", f"{toolchain}.cmake"),
                "-DATTEKF_FIRMWARE_SCALAR=FLOAT"]
    bf.run(cmd, cwd=bf.ROOT)


def _parse(out, where):
    res = {}
    for line in out.splitlines():
        f = line.split()
        if f[:1] == ["peer"]:
            kv = dict(zip(f[3::2], f[4::2]))  # after "peer <name> insns"
            res[f[1]] = {k: (float(v) if k == "tilt_deg" else int(v)) for k, v in kv.items()}
    if not res:
        raise PeerError(f"{where}: no 'peer' lines in the output:\n{out}")
    return res


def _callgrind(bf, args, exe, name, tmp):
    out_file = os.path.join(tmp, f"callgrind.{name}")
    r = subprocess.run(["valgrind", "--tool=callgrind", "--toggle-collect=peers_measured_step",
                        f"--callgrind-out-file={out_file}", exe, str(args.samples), name],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise PeerError(f"callgrind of {name} failed (exit {r.returncode}):\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
    total = None
    with open(out_file, encoding="utf-8") as f:
        for line in f:
            if line.startswith(("summary:", "totals:")):
                total = int(line.split()[1])
    n = _parse(r.stdout, exe)[name]["n"]
    if total is None or n == 0:
        raise PeerError(f"{out_file}: no totals")
    return total / n


def measure(args, results, bf):
    """Peers' figures per preset of results (float builds) and on the host."""
    src = os.path.join(args.build_root or os.path.join(bf.ROOT, "build"), "peers-src")
    fetch(src, log=lambda m: bf.log(args, m))
    peers = {}
    for preset in results:
        if preset.endswith("-fixed"):
            continue
        bdir = _tree(bf, args, preset)
        _configure(bf, args, bdir, src, toolchain=bf.TOOLCHAINS[preset])
        bf.log(args, f"building the peers' images in {os.path.relpath(bdir, bf.ROOT)}")
        bf.run(["cmake", "--build", bdir, "--target", "attekf_peers_bench"] +
               [f"attekf_peer_{p}_footprint" for p in FOOTPRINT.values()], cwd=bf.ROOT)
        tdir = os.path.join(bdir, "firmware", "target", "peers")
        bf.log(args, f"{preset}: running the peers under QEMU (-icount shift=8, {args.samples} samples)")
        out = bf.run([bf.RUNNER, "--machine", bf.MACHINES[preset], "--icount", "8",
                      os.path.join(tdir, "attekf_peers_bench.elf"), str(args.samples)] + list(PEERS))
        peers[preset] = _parse(out, preset)
        for p, short in FOOTPRINT.items():
            fp = bf.footprint_of(os.path.join(tdir, f"attekf_peer_{short}_footprint.elf"),
                                 f"libattekf_peer_{short}.a", bdir)
            peers[preset][p]["flash"] = sum(c["text"] + c["data"] for c in fp["groups"].values())
            peers[preset][p]["ram"] = sum(c["data"] + c["bss"] for c in fp["groups"].values())
    if shutil.which("valgrind") is None:
        bf.log(args, "valgrind not found: no host figures")
        return peers
    hdir = _tree(bf, args, "host")
    _configure(bf, args, hdir, src, build_type="RelWithDebInfo")
    bf.log(args, f"building the host program in {os.path.relpath(hdir, bf.ROOT)}")
    bf.run(["cmake", "--build", hdir, "--target", "attekf_peers_bench"], cwd=bf.ROOT)
    exe = os.path.join(hdir, "firmware", "target", "peers", "attekf_peers_bench")
    peers["host"] = {}
    with tempfile.TemporaryDirectory(dir=hdir) as tmp:
        for name in ("ours",) + PEERS:
            bf.log(args, f"host: callgrind of {name}")
            peers["host"][name] = _callgrind(bf, args, exe, name, tmp)
    return peers


def report(args, results, peers):
    presets = [p for p in results if p in peers]
    cols = presets + (["host"] if "host" in peers else [])
    print("\n### Peers on the same boards\n")
    print("Instructions per full update (gyroscope + accelerometer + magnetometer; ours: `att_step`, "
          "predict and the three updates) on the same samples (bench.c's, after the alignment), "
          "min / mean / max; host x86-64: callgrind instructions per sample (RelWithDebInfo, gcc); "
          "`attekf / it`: attekf's mean over the peer's.\n")
    print("| filter | " + " | ".join(f"{c} | attekf / it" for c in cols) + " |")
    print("|---|" + "---|---|" * len(cols))
    ours = {p: results[p]["bench"]["insns"]["step"]["mean"] for p in presets}
    if "host" in peers:
        ours["host"] = peers["host"]["ours"]

    def cell(c, v):
        if c == "host":
            return f"{v:,.0f}"
        return f"{v['min']:,} / **{v['mean']:,}** / {v['max']:,}"

    row = []
    for c in cols:
        row += [cell(c, results[c]["bench"]["insns"]["step"] if c != "host" else ours["host"]), "1"]
    print("| **attekf** `att_step` | " + " | ".join(row) + " |")
    for stage, label in (("predict", "att_predict"), ("update_gyro", "att_update_gyro"),
                         ("update_accel", "att_update_accel"), ("update_mag", "att_update_mag")):
        row = []
        for c in cols:
            row += [cell(c, results[c]["bench"]["insns"][stage]) if c != "host" else "-", ""]
        print(f"| attekf, stage alone: {label} | " + " | ".join(row) + " |")
    for name in PEERS:
        row = []
        for c in cols:
            v = peers[c][name]
            mean = v if c == "host" else v["mean"]
            row += [cell(c, v), f"{ours[c] / mean:.1f}"]
        print(f"| {name} | " + " | ".join(row) + " |")
    print("\nMemory (flash: the filter's objects with every library member they pull in, from the "
          "link map of a minimal image; RAM: their .data + .bss; state: the filter object; stack: "
          "deepest single update, painted; 128 means at most 128):\n")
    print("| filter | " + " | ".join(f"{p} flash / RAM / state / stack (B)" for p in presets) + " |")
    print("|---|" + "---|" * len(presets))
    row = []
    for p in presets:
        r = results[p]
        ram = sum(c["data"] + c["bss"] for c in r["fp"]["groups"].values())
        row.append(f"{r['flash_all']:,} / {ram:,} / {r['bench']['filter_bytes']:,} / {r['bench']['stack_step']:,}")
    print("| **attekf** | " + " | ".join(row) + " |")
    for name in PEERS:
        print(f"| {name} | " + " | ".join(
            f"{peers[p][name]['flash']:,} / {peers[p][name]['ram']:,} / {peers[p][name]['state']:,} / "
            f"{peers[p][name]['stack']:,}" for p in presets) + " |")
    print("\nSanity check, tilt error at the end of the run (deg): " + "; ".join(
        f"{p}: " + ", ".join(f"{n} {peers[p][n]['tilt_deg']:.3f}" for n in PEERS) for p in presets) +
        f". Sources: imufusion {PINNED['imufusion'][0]}, vqf {PINNED['vqf'][0]} (sdists, SHA-256 pinned in "
        "scripts/bench_peers.py).")
