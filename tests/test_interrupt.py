"""Stopping a parallel test run ends its workers at once (tests/interrupt.py), even while
a worker is inside a long call: here a test sleeping 120 s, in the suite an XLA compilation."""
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

from tests.interrupt import workers

ROOT = pathlib.Path(__file__).parent.parent
LONG = 120


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _outside_pytest() -> dict:
    """This process's environment without what pytest and xdist set in it (a worker's
    PYTEST_XDIST_WORKER would make the run's controller act as a worker)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    return dict(env, PYTHONPATH=str(ROOT))


@pytest.mark.smoke
@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "terminated"])
def test_stopping_the_run_ends_its_workers_at_once(tmp_path, stop):
    mark = tmp_path / "started"
    (tmp_path / "test_long.py").write_text(
        f"import pathlib, time\ndef test_long():\n    pathlib.Path({str(mark)!r}).touch()\n    time.sleep({LONG})\n")
    # as a terminal starts it: SIGINT handled (a worker of this run has it ignored, and a
    # child inherits that); no preexec_fn, which would fork a process that has JAX's threads
    argv = ["-p", "tests.interrupt", "-n", "1", "-p", "no:cacheprovider", "-q", "--rootdir", str(tmp_path),
            str(tmp_path)]
    start_pytest = ("import signal, sys, pytest; signal.signal(signal.SIGINT, signal.default_int_handler); "
                    f"sys.exit(pytest.main({argv!r}))")
    run = subprocess.Popen([sys.executable, "-c", start_pytest], cwd=tmp_path, env=_outside_pytest(),
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while not mark.exists():
            assert run.poll() is None
            time.sleep(0.1)
        (worker,) = workers(run.pid)
        run.send_signal(stop)
        start = time.monotonic()
        while _alive(worker) and time.monotonic() - start < LONG:
            time.sleep(0.1)
        assert time.monotonic() - start < 5.0  # not LONG
    finally:
        run.kill()
        run.wait()
