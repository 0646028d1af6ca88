"""The benchmarks' peak memory is the measuring process's own (``VmHWM``), not the peak that
``ru_maxrss`` carries over from the parent that started it."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps.benchmarks.peak import peak_rss_mb

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(),
                                reason="VmHWM needs Linux's /proc")

#: the child: its own peak before and after touching 200 MB, and what ru_maxrss says
CHILD = """
import json, resource
import numpy as np
from pathpref.apps.benchmarks.peak import peak_rss_mb
before = peak_rss_mb()
a = np.ones(200 * 2**20 // 8)
print(json.dumps({"before": before, "after": peak_rss_mb(),
                  "ru_maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def test_a_child_reports_its_own_peak_not_its_parents():
    parent = np.ones(600 * 2**20 // 8)  # 600 MB touched here, in the parent
    assert peak_rss_mb() >= 600
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).parent.parent)
    child = json.loads(out.stdout.splitlines()[-1])
    del parent
    # the parent's 600 MB is not the child's: an interpreter with NumPy is well under 300 MB
    assert child["before"] < 300
    # the reading follows the child's own memory: 200 MB more (less page rounding)
    assert child["after"] - child["before"] >= 190
    # what the benchmarks used to read: the parent's peak, carried over by fork and exec
    assert child["ru_maxrss"] >= 600


def test_vmhwm_is_read_from_status_and_ru_maxrss_stands_in(tmp_path):
    status = tmp_path / "status"
    status.write_text("Name:\tpython\nVmHWM:\t  123456 kB\n")
    assert peak_rss_mb(status) == pytest.approx(123456 / 1024)
    assert peak_rss_mb(tmp_path / "missing") > 0  # ru_maxrss stands in
