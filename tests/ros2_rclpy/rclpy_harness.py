"""Child programs of the rclpy tests: started with ``--owner-pid``, logs in files, stopped by PID."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence


class Program:
    """A uniros program in a child process, stopped by PID; ``wait_ready`` reads its log for a line."""

    def __init__(self, argv: Sequence[str], log_path: str) -> None:
        self.log_path = log_path
        self._log = open(log_path, "w")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen([*argv, "--owner-pid", str(os.getpid())], stdout=self._log,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)

    def log(self) -> str:
        with open(self.log_path) as f:
            return f.read()

    def wait_ready(self, marker: str = "ready", timeout: float = 90.0) -> None:
        deadline = time.monotonic() + timeout
        while marker not in self.log():
            if self.proc.poll() is not None:
                raise AssertionError(f"{self.proc.args[0]} exited with {self.proc.returncode}:\n{self.log()[-3000:]}")
            if time.monotonic() > deadline:
                raise AssertionError(f"not ready within {timeout:g} s:\n{self.log()[-3000:]}")
            time.sleep(0.05)

    def kill(self) -> None:
        """SIGKILL: the program dies without saying goodbye to the graph."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self._log.close()


def uniros_script(name: str) -> str:
    return os.path.join(os.path.dirname(sys.executable), name)
