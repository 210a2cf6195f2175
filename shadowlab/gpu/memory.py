"""Peak resident memory of this process (Linux: ``VmHWM`` of /proc/self/status), so that every
measurement and run can report what it needed.

The kernel keeps the peak since the process started; writing ``5`` to /proc/self/clear_refs
resets it to the current resident size (Linux ≥ 4.0, proc(5)), which gives the peak *during* one
measurement. Where that is not possible the peak since the process started is reported
(``getrusage``), which can only over-state a measurement's own peak.
"""
from __future__ import annotations

import resource
from pathlib import Path

_STATUS = Path("/proc/self/status")
_CLEAR_REFS = Path("/proc/self/clear_refs")


def reset_peak() -> bool:
    """Start a new peak at the current resident size; False where the platform cannot."""
    try:
        _CLEAR_REFS.write_text("5")
        return True
    except OSError:
        return False


def peak_bytes() -> int:
    """Peak resident set size, bytes: since the last :func:`reset_peak` (or process start)."""
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024  # the kernel reports kB
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: kB


def mib(n_bytes: int) -> float:
    """Bytes in MiB."""
    return n_bytes / 2**20


def available_bytes() -> int | None:
    """Memory the system could give this process now without swapping, bytes (Linux:
    ``MemAvailable`` of /proc/meminfo); None where unknown."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None
