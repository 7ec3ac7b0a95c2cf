"""The ``designlab`` command ends without the interpreter's teardown (``cli.app._exit_now``); what
normal exit would have closed must not outlive it: multiprocessing's resource tracker, started
by a sweep's process pools."""

import subprocess
import sys

SCRIPT = """
import os
from multiprocessing import resource_tracker
resource_tracker.ensure_running()
pid = resource_tracker._resource_tracker._pid
os.kill(pid, 0)                                 # running
from designlab.cli.app import _stop_resource_tracker
_stop_resource_tracker()
try:
    os.kill(pid, 0)
except ProcessLookupError:
    print("gone")
else:
    print("alive")
_stop_resource_tracker()                        # nothing to stop: no error
"""


def test_exit_stops_the_resource_tracker():
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "gone"
