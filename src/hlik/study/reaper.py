"""Ray's processes end with the study, even when the study is killed outright.

``ray.shutdown()`` stops the local cluster when the study ends or is interrupted, but a command
killed by SIGKILL (or the OOM killer) runs no code: Ray's raylet and GCS go with it, while its
dashboard and runtime-env agents keep running (measured with Ray 2.60: still there a minute later).
:func:`start_reaper` starts a small watcher process that notes every process the study's process
starts (its descendants, on Linux, from ``/proc``) and, once that process is gone, ends those
still running (SIGTERM, then SIGKILL), the ones it noted and no others.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

# The watcher, run as ``python -c WATCHER DRIVER_PID``. It ignores SIGINT (Ctrl-C reaches the
# whole process group), lives while its parent is the driver and then reaps what it noted; a
# process is reaped only if its command line is still the one last noted (no PID reused by another).
WATCHER = r"""
import os, signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
driver, me = int(sys.argv[1]), os.getpid()

def cmdline(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read()
    except OSError:
        return None

def descendants():
    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parents[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                pass
    found, todo = set(), [driver]
    while todo:
        pid = todo.pop()
        for child, parent in parents.items():
            if parent == pid and child not in found and child != me:
                found.add(child)
                todo.append(child)
    return found

seen = {}
while os.getppid() == driver:
    for pid in descendants():
        seen[pid] = cmdline(pid)  # the latest: Ray's agents rename themselves after they start
    time.sleep(0.5)
for sig in (signal.SIGTERM, signal.SIGKILL):
    alive = [p for p, c in seen.items() if c is not None and cmdline(p) == c]
    for pid in alive:
        try:
            os.kill(pid, sig)
        except OSError:
            pass
    if alive and sig == signal.SIGTERM:
        time.sleep(2.0)
"""


def start_reaper() -> subprocess.Popen | None:
    """Start the watcher for this process (Linux only; None elsewhere). Start it before Ray, so
    that it notes Ray's processes as they start."""
    if not Path("/proc/self/stat").exists():
        return None
    return subprocess.Popen(
        [sys.executable, "-c", WATCHER, str(os.getpid())],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # a signal to the study's process group does not reach it
    )
