"""A test's folder and the farm processes it starts on 127.0.0.1, and the arguments ctest
gives, for the tests that run the built binaries (python_client_test.py,
dashboard_browser_test.py): they import it from beside them, the folder Python puts first
on sys.path for the script it runs.

Each process runs in a session of its own, its output in <log name>.log in the folder, and
is killed when the test stops it (and by the kernel if the test's process dies: setpriv
--pdeathsig). The folder is removed after a success unless TESSERA_KEEP_TEST_DIRS is set,
and kept, with the logs' tails printed, after a failure.
"""

import argparse
import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def farm_argument_parser(description):
    """A parser of the arguments that ctest gives these tests (tests/CMakeLists.txt): the
    built binaries and the repository; a test adds its own."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--tessera", required=True, help="the tessera CLI")
    parser.add_argument("--coordinator", required=True, help="tessera-coordinator")
    parser.add_argument("--worker", required=True, help="tessera-worker")
    parser.add_argument("--source-dir", required=True, help="the repository (for scenes/)")
    return parser


class FarmProcesses:
    """The folder (a fresh one named `prefix`...) and the processes started in it; `cli`
    runs the `tessera` command at `tessera`, for at most `cli_deadline_s` seconds."""

    def __init__(self, prefix, tessera, cli_deadline_s):
        self.dir = Path(tempfile.mkdtemp(prefix=prefix))
        self.processes = []
        self.logs = []
        self.tessera = tessera
        self.cli_deadline_s = cli_deadline_s

    def start(self, argv, log_name, env=None):
        log = self.dir / f"{log_name}.log"
        self.logs.append(log)
        # The kernel kills the child if this process dies without its cleanup.
        prefix = ["setpriv", "--pdeathsig", "KILL", "--"] if shutil.which("setpriv") else []
        with open(log, "ab") as out:
            p = subprocess.Popen(
                prefix + [str(a) for a in argv],
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                env=env,
            )
        self.processes.append(p)
        return p

    def cli(self, *args):
        """Runs the `tessera` command to its end; returns its stdout."""
        r = subprocess.run(
            [self.tessera, *map(str, args)],
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=self.cli_deadline_s,
        )
        if r.returncode != 0:
            command = " ".join(map(str, args))
            raise AssertionError(f"tessera {command} exited {r.returncode}:\n{r.stderr}")
        return r.stdout

    def log_tails(self, lines=40):
        text = []
        for log in self.logs:
            tail = log.read_text(errors="replace").splitlines()[-lines:] if log.exists() else []
            text.append(f"--- {log.name} ---\n" + "\n".join(tail))
        return "\n".join(text)

    def stop(self):
        for p in self.processes:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
        for p in self.processes:
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(timeout=30)
        self.processes = []

    def finish(self, ok, kept="logs and outputs"):
        """Stops the processes; removes the folder after a success (`ok`), else prints the
        logs' tails and where `kept` (what the folder holds) is."""
        self.stop()
        if ok and not os.environ.get("TESSERA_KEEP_TEST_DIRS"):
            shutil.rmtree(self.dir, ignore_errors=True)
        else:
            sys.stderr.write(f"\n{self.log_tails()}\n{kept} kept in {self.dir}\n")


def wait_for(what, condition, deadline_s=60, interval_s=0.1, on_timeout=None, retry_on=()):
    """Polls condition() until it returns something true; returns that value. Exceptions
    of the types in `retry_on` count as "not yet". Fails with `what` (and on_timeout()'s
    text) after the deadline."""
    deadline = time.monotonic() + deadline_s
    last_error = None
    while time.monotonic() < deadline:
        try:
            value = condition()
            if value:
                return value
        except retry_on as e:
            last_error = e
        time.sleep(interval_s)
    detail = on_timeout() if on_timeout else ""
    raise AssertionError(f"timed out waiting for {what} {last_error or ''}\n{detail}")
