"""Stopping the test run stops its workers at once. pytest-xdist's workers ignore SIGINT
and stop only between tests, when the controller tells them to (or execnet kills them); a
controller that was terminated leaves them running to the end of their test, which in
this suite is often an XLA compilation of minutes. Now an interrupted controller ends its
workers (SIGTERM) at once, and a worker whose controller is gone exits within a second."""
import os
import signal
import subprocess
import threading
import time


def workers(parent: int) -> list[int]:
    """The pids of ``parent``'s child processes."""
    if os.path.isdir("/proc"):
        found = []
        for entry in os.listdir("/proc"):
            try:
                with open(f"/proc/{entry}/stat") as f:
                    stat = f.read()
            except (OSError, ValueError):
                continue
            if entry.isdigit() and int(stat.rsplit(")", 1)[1].split()[1]) == parent:
                found.append(int(entry))
        return found
    done = subprocess.run(["pgrep", "-P", str(parent)], capture_output=True, text=True)
    return [int(pid) for pid in done.stdout.split()]


def pytest_keyboard_interrupt(excinfo):
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    for pid in workers(os.getpid()):
        try:
            os.kill(pid, signal.SIGTERM)
        except ProcessLookupError:
            pass


def _exit_when_orphaned(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(1)


def pytest_configure(config):
    if os.environ.get("PYTEST_XDIST_WORKER"):
        threading.Thread(target=_exit_when_orphaned, args=(os.getppid(),), daemon=True).start()
