"""A process's own peak memory, for the benchmarks that run a measurement in a fresh process.

``getrusage(RUSAGE_SELF).ru_maxrss`` is not that process's own peak on Linux: ``execve`` folds
the peak of the memory image it replaces into the new program's ``ru_maxrss``, and a child made
by ``fork`` or ``vfork`` starts from its parent's image, so a child of a 1 GB parent reports at
least 1 GB whatever it uses itself. ``VmHWM`` in ``/proc/self/status`` is the high-water mark of
the resident set of the process's current address space only, created at ``execve``: the
child's own peak.
"""

from __future__ import annotations

import resource
from pathlib import Path

_STATUS = Path("/proc/self/status")


def peak_rss_mb(status: Path = _STATUS) -> float:
    """This process's own peak resident set in MB (MiB): ``VmHWM`` of ``status`` (kB / 1024).
    Where ``/proc`` is missing (not Linux), ``ru_maxrss`` (kB on Linux and BSD) stands in: an
    upper bound there, which includes the memory of the image ``execve`` replaced."""
    try:
        for line in status.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
