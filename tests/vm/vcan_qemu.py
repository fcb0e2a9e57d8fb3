"""The QEMU backend of vcan_run.py (docs/hil.md): a full Linux guest, for machines
where neither the host kernel nor user-mode Linux can run vcan.

``qemu-system-x86_64 -machine q35`` boots Debian's own ``linux-image-amd64`` kernel (it has
``can``, ``can-raw``, ``can-bcm``, ``can-dev``, ``vcan`` and ``9p`` as modules; the ``cloud``
flavour has neither CAN nor 9p). The kernel and those modules come from the Debian package,
fetched with ``apt-get download`` and unpacked with ``dpkg-deb -x`` into the project's cache
(:func:`prepare_kernel`, run by scripts/setup.sh). An initramfs built at run time (static
busybox and the modules, loaded with insmod in dependency order) mounts the host's ``/`` over
virtio-9p (``cache=loose``: Python's imports take about 3 s instead of 9-14 s) and makes it the
root with ``switch_root``; the init script of vcan_guest then runs as under UML. Kernel options
``tsc=reliable clocksource=tsc``: without them the guest clock advances in 4 ms steps under TCG.
The kernel boots through its PVH entry from the ELF image inside the package's compressed
bzImage, unpacked once on the host: decompressing it in the emulated guest took about 11 s.

One virtual CPU, like UML: under TCG a second one doubled the emulation's CPU time (Python
started in 3.9-6.8 s instead of 1.6-3.9 s on a loaded 2-core host).

KVM is tried only where the CPU has the vmx or svm flag and /dev/kvm is usable
(vcan_choice.kvm_precheck); a guest that prints nothing on its console within KVM_MARKER_S
seconds is given up. A /dev/kvm without working virtualisation has been seen both to hang a
guest silently and to make QEMU exit at once with an error (docs/hil.md, "Machines seen"):
either way the runner reports what it saw and goes on to TCG (emulation).

Standard library only."""

from __future__ import annotations

import glob
import gzip
import hashlib
import lzma
import os
import re
import shutil
import stat
import struct
import subprocess
import tempfile
import zlib
from typing import Dict, List, Optional, Sequence, Tuple

import vcan_choice as choice
import vcan_guest as g

QEMU = "qemu-system-x86_64"
KERNEL_PACKAGE = "linux-image-amd64"
# What the guest needs, as module names; their dependencies are found in the modules.
TARGET_MODULES = ("virtio_pci", "9pnet_virtio", "9p", "can_raw", "can_bcm", "vcan")
BUSYBOX = ("/bin/busybox", "/usr/bin/busybox")
KVM_MARKER_S = 6.0
DEFAULT_MEM_MB = 1024
# cryptomgr.notests: the crypto self-tests cost about 1 s of emulated boot and test nothing of ours
APPEND = ("console=ttyS0 panic=-1 tsc=reliable clocksource=tsc 8250.nr_uarts=1 cryptomgr.notests "
          "rdinit=/init")


def kernel_cache() -> str:
    return os.path.join(g.cache_dir(), "qemu-kernel")


# ---------------------------------------------------------------------------------------------
# Kernel modules: dependencies from each module's .modinfo section
# ---------------------------------------------------------------------------------------------
def _module_bytes(path: str) -> bytes:
    with open(path, "rb") as fh:
        data = fh.read()
    return lzma.decompress(data) if path.endswith(".xz") else data


def modinfo(path: str) -> Dict[str, str]:
    """The key=value strings of a kernel module's .modinfo ELF section."""
    data = _module_bytes(path)
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        raise ValueError(f"{path}: not a 64-bit little-endian ELF module")
    shoff = struct.unpack_from("<Q", data, 0x28)[0]
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x3A)
    secs = [struct.unpack_from("<IIQQQQ", data, shoff + i * shentsize) for i in range(shnum)]
    strtab_off = secs[shstrndx][4]
    for name_off, _typ, _flags, _addr, off, size in secs:
        end = data.index(b"\0", strtab_off + name_off)
        if data[strtab_off + name_off:end] == b".modinfo":
            info: Dict[str, str] = {}
            for item in data[off:off + size].split(b"\0"):
                if b"=" in item:
                    k, v = item.decode("utf-8", "replace").split("=", 1)
                    info.setdefault(k, v)
            return info
    raise ValueError(f"{path}: no .modinfo section")


def _norm(name: str) -> str:
    return name.replace("-", "_")


def module_order(tree: str, targets: Sequence[str] = TARGET_MODULES) -> List[str]:
    """Paths of the target modules and their dependencies under tree, each after what it
    depends on (built-in ones, listed in modules.builtin, left out)."""
    files: Dict[str, str] = {}
    builtin = set()
    for path in glob.glob(os.path.join(tree, "**", "*.ko*"), recursive=True):
        base = os.path.basename(path)
        files[_norm(base.split(".ko")[0])] = path
    for bfile in glob.glob(os.path.join(tree, "**", "modules.builtin"), recursive=True):
        for line in g.read_text(bfile).split():
            builtin.add(_norm(os.path.basename(line).split(".ko")[0]))
    order: List[str] = []
    done = set()
    # depth-first with an explicit stack (dependency chains are short; no recursion)
    for target in targets:
        stack: List[Tuple[str, bool]] = [(_norm(target), False)]
        while stack:
            name, expanded = stack.pop()
            if name in done:
                continue
            if name not in files:
                if name in builtin:
                    done.add(name)
                    continue
                raise FileNotFoundError(f"kernel module {name} not in {tree}")
            if expanded:
                done.add(name)
                order.append(files[name])
                continue
            stack.append((name, True))
            deps = [d for d in modinfo(files[name]).get("depends", "").split(",") if d]
            stack.extend((_norm(d), False) for d in reversed(deps) if _norm(d) not in done)
    return order


# ---------------------------------------------------------------------------------------------
# The Debian kernel in the project's cache
# ---------------------------------------------------------------------------------------------
def _apt(args: List[str], cwd: Optional[str] = None) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, cwd=cwd, stdin=subprocess.DEVNULL)


def _kernel_package() -> Tuple[str, str]:
    """The versioned package linux-image-amd64 depends on, and its version."""
    dep = _apt(["apt-cache", "depends", KERNEL_PACKAGE])
    m = re.search(r"Depends:\s*(linux-image-\S+)", dep.stdout)
    if not m:
        raise RuntimeError(f"apt-cache depends {KERNEL_PACKAGE}: no linux-image dependency "
                           f"({(dep.stderr or dep.stdout).strip()[:200]}); run apt-get update")
    pkg = m.group(1)
    show = _apt(["apt-cache", "show", "--no-all-versions", pkg])
    v = re.search(r"^Version:\s*(\S+)", show.stdout, re.M)
    if not v:
        raise RuntimeError(f"apt-cache show {pkg}: no version")
    return pkg, v.group(1)


def pvh_vmlinux(vmlinuz: str, out: str) -> bool:
    """Writes the ELF kernel inside a bzImage to out if it has a PVH entry (Xen note 18,
    XEN_ELFNOTE_PHYS32_ENTRY) and a payload this Python can decompress; False otherwise."""
    with open(vmlinuz, "rb") as fh:
        d = fh.read()
    if d[0x202:0x206] != b"HdrS" or struct.unpack_from("<H", d, 0x206)[0] < 0x208:
        return False
    setup_sects = d[0x1F1] or 4
    payload_offset, payload_length = struct.unpack_from("<II", d, 0x248)
    start = (setup_sects + 1) * 512 + payload_offset
    payload = d[start:start + payload_length]
    if payload[:6] == b"\xfd7zXZ\x00":
        elf = lzma.LZMADecompressor(format=lzma.FORMAT_XZ).decompress(payload)
    elif payload[:2] == b"\x1f\x8b":
        elf = zlib.decompressobj(31).decompress(payload)   # ignores the appended size
    else:
        return False
    if elf[:4] != b"\x7fELF" or not _has_pvh_note(elf):
        return False
    tmp = f"{out}.{os.getpid()}.tmp"
    with open(tmp, "wb") as fh:
        fh.write(elf)
    os.replace(tmp, out)
    return True


def _has_pvh_note(elf: bytes) -> bool:
    phoff = struct.unpack_from("<Q", elf, 0x20)[0]
    phentsize, phnum = struct.unpack_from("<HH", elf, 0x36)
    for i in range(phnum):
        p_type, _flags, off, _va, _pa, filesz = struct.unpack_from("<IIQQQQ", elf, phoff + i * phentsize)
        if p_type != 4:                       # PT_NOTE
            continue
        pos, end = off, off + filesz
        while pos + 12 <= end:
            namesz, descsz, ntype = struct.unpack_from("<III", elf, pos)
            name = elf[pos + 12:pos + 12 + namesz].rstrip(b"\0")
            if name == b"Xen" and ntype == 18:
                return True
            pos += 12 + (namesz + 3) // 4 * 4 + (descsz + 3) // 4 * 4
    return False


def cached_kernel() -> Optional[Dict[str, str]]:
    """The newest kernel in the cache: {"dir", "vmlinuz", "package"}, or None."""
    best = None
    for stamp in glob.glob(os.path.join(kernel_cache(), "*", "package")):
        d = os.path.dirname(stamp)
        if os.path.exists(os.path.join(d, "vmlinuz")) and os.path.exists(os.path.join(d, "modules.order")):
            t = os.path.getmtime(stamp)
            if best is None or t > best[0]:
                best = (t, d)
    if best is None:
        return None
    d = best[1]
    return {"dir": d, "vmlinuz": os.path.join(d, "vmlinuz"), "vmlinux": os.path.join(d, "vmlinux"),
            "package": g.read_text(os.path.join(d, "package")).strip()}


def boot_image(kernel: Dict[str, str]) -> str:
    """The image to give QEMU's -kernel: the PVH ELF kernel (unpacked once into the cache),
    else the bzImage."""
    if os.path.exists(kernel["vmlinux"]) or pvh_vmlinux(kernel["vmlinuz"], kernel["vmlinux"]):
        return kernel["vmlinux"]
    return kernel["vmlinuz"]


def prepare_kernel(log=print) -> Dict[str, str]:
    """Makes sure the cache holds the kernel of the current linux-image-amd64: downloads the
    package with apt-get download, unpacks it with dpkg-deb -x, keeps the kernel image and the
    modules the guest needs (with their load order). Returns cached_kernel()."""
    try:
        pkg, ver = _kernel_package()
    except (RuntimeError, OSError) as e:
        have = cached_kernel()
        if have:
            log(f"qemu: cannot look up {KERNEL_PACKAGE} ({e}); using the cached {have['package']}")
            return have
        raise RuntimeError(str(e)) from e
    dest = os.path.join(kernel_cache(), f"{pkg}_{ver}")
    if os.path.exists(os.path.join(dest, "package")):
        return cached_kernel() or {}
    os.makedirs(kernel_cache(), exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="kernel.", dir=kernel_cache())
    try:
        os.chmod(tmp, 0o755)     # apt's download sandbox user must be able to write there
        dl = _apt(["apt-get", "download", f"{pkg}={ver}"], cwd=tmp)
        if dl.returncode != 0:
            _apt(["apt-get", "update", "-qq"])
            dl = _apt(["apt-get", "download", f"{pkg}={ver}"], cwd=tmp)
        debs = glob.glob(os.path.join(tmp, "*.deb"))
        if dl.returncode != 0 or not debs:
            raise RuntimeError(f"apt-get download {pkg}={ver} failed: {(dl.stderr or dl.stdout).strip()[-300:]}")
        log(f"qemu: unpacking {os.path.basename(debs[0])}")
        x = _apt(["dpkg-deb", "-x", debs[0], os.path.join(tmp, "x")])
        if x.returncode != 0:
            raise RuntimeError(f"dpkg-deb -x {os.path.basename(debs[0])} failed: {x.stderr.strip()[-300:]}")
        vmlinuz = sorted(glob.glob(os.path.join(tmp, "x", "boot", "vmlinuz-*")))
        trees = sorted(glob.glob(os.path.join(tmp, "x", "lib", "modules", "*")))
        if not vmlinuz or not trees:
            raise RuntimeError(f"{pkg}: no /boot/vmlinuz-* or /lib/modules/* in the package")
        order = module_order(trees[0])
        stage = os.path.join(tmp, "stage")
        os.makedirs(os.path.join(stage, "modules"))
        shutil.copy2(vmlinuz[0], os.path.join(stage, "vmlinuz"))
        pvh_vmlinux(os.path.join(stage, "vmlinuz"), os.path.join(stage, "vmlinux"))
        names = []
        for path in order:
            name = os.path.basename(path)
            shutil.copy2(path, os.path.join(stage, "modules", name))
            names.append(name)
        with open(os.path.join(stage, "modules.order"), "w") as fh:
            fh.write("\n".join(names) + "\n")
        with open(os.path.join(stage, "package"), "w") as fh:
            fh.write(f"{pkg} {ver} {os.path.basename(trees[0])}\n")
        shutil.rmtree(dest, ignore_errors=True)
        os.replace(stage, dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for old in glob.glob(os.path.join(kernel_cache(), "linux-image-*")):
        if old != dest:
            shutil.rmtree(old, ignore_errors=True)
    return cached_kernel() or {}


# ---------------------------------------------------------------------------------------------
# The initramfs: busybox, the modules, an init that switches to the host's / over 9p
# ---------------------------------------------------------------------------------------------
def _cpio(entries: List[Tuple[str, int, bytes, int, int]]) -> bytes:
    """A cpio archive in the kernel's "newc" format: (name, mode, data, rdev major, minor)."""
    out = bytearray()

    def put(name: str, mode: int, data: bytes, ino: int, rmaj: int = 0, rmin: int = 0) -> None:
        nb = name.encode() + b"\0"
        fields = (ino, mode, 0, 0, 1, 0, len(data), 0, 0, rmaj, rmin, len(nb), 0)
        out.extend(b"070701" + b"".join(b"%08X" % f for f in fields) + nb)
        out.extend(b"\0" * (-len(out) % 4))
        out.extend(data)
        out.extend(b"\0" * (-len(out) % 4))

    for i, (name, mode, data, rmaj, rmin) in enumerate(entries, start=1):
        put(name, mode, data, i, rmaj, rmin)
    put("TRAILER!!!", 0, b"", 0)
    return bytes(out)


def _initramfs_init(modules: Sequence[str]) -> str:
    b = "/bin/busybox"
    lines = ["#!/bin/busybox sh",
             f"fail() {{ {b} echo \"vcan_run (guest): initramfs: $*\"; {b} poweroff -f; }}",
             f"{b} echo 'vcan_run: initramfs'",
             f"{b} mount -t proc proc /proc"]
    lines += [f"{b} insmod /lib/modules/{m} || fail 'insmod {m} failed'" for m in modules]
    lines += [
        f"{b} mount -t 9p -o trans=virtio,version=9p2000.L,cache=loose,msize=512000 hostroot /newroot "
        "|| fail 'mount of the host root over 9p failed'",
        f"{b} mount -t proc proc /newroot/proc || fail 'mount proc failed'",
        f"{b} mount -t sysfs sys /newroot/sys || fail 'mount sysfs failed'",
        f"{b} mount -t devtmpfs dev /newroot/dev || fail 'mount devtmpfs failed'",
        f"{b} mkdir -p /newroot/dev/shm /newroot/dev/pts",
        f"{b} mount -t tmpfs shm /newroot/dev/shm",
        f"{b} mount -t devpts pts /newroot/dev/pts",
        f"{b} umount /proc",
        # the init script is the last argument (the kernel passes on to init the options it
        # does not know itself)
        "for a in \"$@\"; do I=$a; done",
        f"[ -x \"/newroot$I\" ] || fail \"no init script $I under the host root\"",
        f"exec {b} switch_root /newroot \"$I\"",
    ]
    return "\n".join(lines) + "\n"


def initramfs(kernel: Dict[str, str]) -> str:
    """Path of the initramfs for this kernel (built once per content into the cache)."""
    busybox = next((p for p in BUSYBOX if os.path.exists(p)), None)
    if busybox is None:
        raise RuntimeError("busybox not found (Debian package busybox-static)")
    with open(busybox, "rb") as fh:
        bb = fh.read()
    if b"/lib64/ld-linux" in bb[:4096] or b"ld-linux-x86-64.so" in bb[:8192]:
        raise RuntimeError(f"{busybox} is dynamically linked (install busybox-static)")
    mods = g.read_text(os.path.join(kernel["dir"], "modules.order")).split()
    init = _initramfs_init(mods)
    h = hashlib.sha256(bb + init.encode() + kernel["package"].encode()).hexdigest()[:16]
    path = os.path.join(kernel["dir"], f"initramfs-{h}.img")
    if os.path.exists(path):
        return path
    entries: List[Tuple[str, int, bytes, int, int]] = [
        (d, stat.S_IFDIR | 0o755, b"", 0, 0) for d in ("bin", "dev", "proc", "sys", "newroot", "lib", "lib/modules")]
    entries.append(("dev/console", stat.S_IFCHR | 0o600, b"", 5, 1))
    entries.append(("bin/busybox", stat.S_IFREG | 0o755, bb, 0, 0))
    entries.append(("bin/sh", stat.S_IFLNK | 0o777, b"busybox", 0, 0))
    for m in mods:
        entries.append((f"lib/modules/{m}", stat.S_IFREG | 0o644,
                        _module_bytes(os.path.join(kernel["dir"], "modules", m)), 0, 0))
    entries.append(("init", stat.S_IFREG | 0o755, init.encode(), 0, 0))
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "wb") as fh:
        fh.write(gzip.compress(_cpio(entries), compresslevel=1))
    os.replace(tmp, path)
    return path


# ---------------------------------------------------------------------------------------------
# Boot
# ---------------------------------------------------------------------------------------------
def available() -> Optional[str]:
    """Why QEMU cannot be used here (TCG), or None if it can."""
    if shutil.which(QEMU) is None:
        return f"{QEMU} not found (Debian package qemu-system-x86)"
    if not any(os.path.exists(p) for p in BUSYBOX):
        return "busybox not found (Debian package busybox-static)"
    if cached_kernel() is None:
        return (f"no guest kernel in {kernel_cache()} (scripts/setup.sh fetches Debian's "
                f"{KERNEL_PACKAGE}; or tests/vm/vcan_run.py --prepare)")
    return None


def kvm_device() -> Tuple[bool, bool]:
    """Whether /dev/kvm exists, and whether this user may open it read-write."""
    return os.path.exists("/dev/kvm"), os.access("/dev/kvm", os.R_OK | os.W_OK)


def kvm_usable(check_flags: bool = True) -> Optional[str]:
    """Why KVM is not to be tried here, or None (check_flags=False: try it on a CPU without
    vmx/svm too)."""
    return choice.kvm_precheck(g.cpu_flags(), *kvm_device(), check_flags=check_flags)


def run(cmd: str, ifaces: Sequence[str], timeout: float, env: Dict[str, str], cwd: str,
        keep: bool, accel: str, mem_mb: int = DEFAULT_MEM_MB, smp: int = 1) -> choice.Result:
    """Runs cmd in a QEMU guest; accel "kvm" or "tcg" (vcan_run checks first that it is
    usable: available(), kvm_usable()). Raises BackendError."""
    backend = f"qemu-{accel}"
    kernel = cached_kernel() or {}
    try:
        image = boot_image(kernel)
        rd = initramfs(kernel)
    except (RuntimeError, OSError, ValueError) as e:
        raise choice.BackendError(backend, f"cannot build the initramfs: {e}") from e
    work = g.WorkDir(keep)
    try:
        # busybox (static) powers off at once; the sysrq trigger is the fallback
        off = ("/bin/busybox poweroff -f 2>/dev/null; echo o > /proc/sysrq-trigger; "
               "while :; do :; done")
        init = work.file("init.sh")
        with open(init, "w") as fh:
            fh.write(g.init_script(work.path, cmd, ifaces, env, cwd, [], off))
        os.chmod(init, 0o755)
        cpu = ["-accel", "kvm", "-cpu", "host"] if accel == "kvm" else ["-accel", "tcg", "-cpu", "max"]
        argv = [QEMU, "-machine", "q35", *cpu, "-smp", str(smp), "-m", str(mem_mb),
                "-nodefaults", "-no-user-config", "-display", "none", "-no-reboot",
                "-chardev", f"file,id=con,path={work.file('console.log')}", "-serial", "chardev:con",
                "-kernel", image, "-initrd", rd, "-append", f"{APPEND} -- {init}",
                "-fsdev", "local,id=hostroot,path=/,security_model=none,multidevs=remap",
                "-device", "virtio-9p-pci,fsdev=hostroot,mount_tag=hostroot"]
        boot = g.run_guest(argv, work, timeout, output="qemu.log", watch="console.log",
                           marker_s=KVM_MARKER_S if accel == "kvm" else None)
        res = choice.outcome(backend, boot, g.collect(work, boot, extra="qemu.log"), timeout)
        res.notes.append(f"{backend}: kernel {kernel['package'].split()[0]}")
        return res
    finally:
        work.close()
