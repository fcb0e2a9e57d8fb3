"""Generate (or check) the committed C code derived symbolically.

    python -m attekf.codegen            write the generated files
    python -m attekf.codegen --check    exit 1 if a committed file differs from the script
"""

from __future__ import annotations

import argparse
import difflib
import sys
from pathlib import Path
from typing import Callable, Dict, List, Tuple

from . import attitude, covgen, settings_doc
from . import constacc, radar, slam

# (output directory relative to the repository root, builder)
TARGETS: List[Tuple[str, Callable[[], Dict[str, str]]]] = [
    ("firmware/att", attitude.build),
    ("firmware/att", covgen.build),
    ("firmware/models", constacc.build),
    ("firmware/models", radar.build),
    ("firmware/models", slam.build),
]


# Builders of files derived from other committed files: (root -> {path from root: text}).
DERIVED: List[Callable[[Path], Dict[str, str]]] = [settings_doc.build_doc]


def repo_root() -> Path:
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "firmware").is_dir() and (parent / "CMakeLists.txt").is_file():
            return parent
    raise SystemExit("attekf.codegen: cannot find the repository root above " + str(here))


def main(argv: List[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="attekf-codegen", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true",
                    help="compare with the committed files instead of writing them")
    ap.add_argument("--root", type=Path, default=None, help="repository root (default: found)")
    args = ap.parse_args(argv)
    root = args.root or repo_root()
    stale = 0
    outputs = [(root / outdir / name, text) for outdir, builder in TARGETS for name, text in builder().items()]
    outputs += [(root / rel, text) for builder in DERIVED for rel, text in builder(root).items()]
    for path, text in outputs:
        if args.check:
            old = path.read_text() if path.exists() else ""
            if old != text:
                stale += 1
                diff = difflib.unified_diff(old.splitlines(), text.splitlines(),
                                            str(path), "generated", lineterm="", n=1)
                print("\n".join(list(diff)[:40]))
                print(f"STALE: {path} differs from its generator (run python -m attekf.codegen)")
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if args.check and not stale:
        print("generated code is current")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
