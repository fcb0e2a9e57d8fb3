"""Progress bars for long work (tqdm on stderr; none with --quiet or when stderr is not a
terminal, so logs and pipes stay clean). Counts are shown as integers (12/22 runs, 53240
samples): tqdm's unit scaling would print 1.00/12.0."""

from __future__ import annotations

from typing import Iterable, Optional, TypeVar

T = TypeVar("T")


def bar(total: Optional[int], desc: str, quiet: bool = False, unit: str = "it", leave: bool = False):
    """A progress bar to .update(n) and .close() (or use as a context manager). tqdm comes with
    the tools extra (the commands check that it is installed)."""
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit=unit, unit_scale=False, leave=leave,
                disable=True if quiet else None, dynamic_ncols=True)


def iterate(items: Iterable[T], desc: str, quiet: bool = False, total: Optional[int] = None,
            unit: str = "it") -> Iterable[T]:
    """items wrapped in a progress bar."""
    from tqdm import tqdm
    return tqdm(items, desc=desc, unit=unit, total=total, leave=False,
                disable=True if quiet else None, dynamic_ncols=True)
