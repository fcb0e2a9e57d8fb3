"""Where a result comes from: commit, machine, package versions, and the JSON clean-up shared
by `attekf bench`, `attekf cv` and `attekf robustness`."""

from __future__ import annotations

import math
import os
import platform
import subprocess
from typing import Dict, Optional

import numpy as np

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def git_info(repo: str) -> Dict[str, object]:
    """Commit and whether the tree has uncommitted changes (read-only git calls)."""
    def git(*args):
        return subprocess.run(["git", "-C", repo, *args], capture_output=True, text=True, timeout=10)
    try:
        head = git("rev-parse", "--short=12", "HEAD")
        status = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "uncommitted_changes": None}
    if head.returncode != 0:
        return {"commit": None, "uncommitted_changes": None}
    changed = [ln[3:] for ln in status.stdout.splitlines() if ln.strip()]
    out = {"commit": head.stdout.strip(), "uncommitted_changes": bool(changed), "changed_files": changed}
    if changed:   # identifies the working tree's state (tracked files) for a later comparison
        import hashlib
        diff = subprocess.run(["git", "-C", repo, "diff", "HEAD"], capture_output=True, timeout=30)
        out["diff_sha256"] = hashlib.sha256(diff.stdout).hexdigest()[:16]
    return out


def machine_info() -> Dict[str, object]:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {"cpu": cpu, "cpus": os.cpu_count(), "python": platform.python_version(),
            "system": platform.platform()}


def package_versions() -> Dict[str, Optional[str]]:
    from importlib import metadata
    out = {}
    for name in ("vqf", "imufusion", "AHRS", "numpy"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def clean_json(obj):
    """NaN/inf -> None, numpy scalars -> Python (strict JSON)."""
    if isinstance(obj, dict):
        return {k: clean_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean_json(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def display_path(path: str) -> str:
    """A path as results name it: relative to the repository when inside it or next to it
    (build/host/..., ../shared/data/broad), so that no machine's directory ends up in docs."""
    full = os.path.abspath(path)
    parent = os.path.dirname(REPO_ROOT)
    if full == REPO_ROOT or full.startswith(REPO_ROOT + os.sep):
        return os.path.relpath(full, REPO_ROOT)
    if full.startswith(parent + os.sep):
        return os.path.relpath(full, REPO_ROOT)
    return path
