"""One OS process per node, supervised: a restartable node that dies is started again (a bounded
number of times), any other death fails the run. Children never outlive the runner: a tiny
launcher asks the kernel for SIGKILL when its parent dies (Linux ``PR_SET_PDEATHSIG``, kept
across the exec into the node and the ROS wheels' re-exec); each child has its own session, so
a terminal's Ctrl-C reaches only the runner, which stops the children in order.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

# Run with ``python -S`` (no site: the ROS wheels' start-up hook would re-exec first). Exits if
# the runner already died between fork and prctl, then becomes the node.
_LAUNCHER = (
    "import ctypes, os, signal, sys\n"
    "ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)\n"
    "os.getppid() == int(sys.argv[1]) or os._exit(70)\n"
    "os.execv(sys.argv[2], sys.argv[2:])\n"
)


class NodeDied(RuntimeError):
    """A node process ended while the run needed it."""

    def __init__(self, name: str, returncode: int, detail: str = ""):
        how = (
            f"was killed by {signal.Signals(-returncode).name}"
            if returncode < 0 and -returncode in signal.valid_signals()
            else f"exited with status {returncode}"
        )
        super().__init__(f"{name} {how}{detail}")
        self.name = name
        self.returncode = returncode


@dataclass
class NodeProcess:
    name: str
    argv: list[str]
    restartable: bool
    popen: subprocess.Popen | None = None
    restarts: int = 0


class Supervisor:
    """Starts, watches and stops the graph's node processes."""

    def __init__(self, env: dict[str, str], max_restarts: int = 3, log=print):
        self.env = env
        self.max_restarts = max_restarts
        self.nodes: list[NodeProcess] = []
        self.log = log

    def add(self, name: str, params: dict, restartable: bool = False, namespace: str = "") -> None:
        exe = str(Path(sys.executable).parent / name)
        argv = [exe, "--ros-args"] + (["-r", f"__ns:={namespace}"] if namespace else [])
        for k, v in params.items():
            argv += ["-p", f"{k}:={v}"]
        self.nodes.append(NodeProcess(name, argv, restartable))

    def _spawn(self, node: NodeProcess) -> None:
        node.popen = subprocess.Popen(
            [sys.executable, "-S", "-c", _LAUNCHER, str(os.getpid()), *node.argv],
            env=self.env,
            start_new_session=True,
        )

    def start(self) -> None:
        for node in self.nodes:
            self._spawn(node)

    def poll(self) -> None:
        """Restart a restartable node that ended; raise NodeDied for any other."""
        for node in self.nodes:
            code = node.popen.poll() if node.popen else None
            if code is None:
                continue
            if node.restartable and node.restarts < self.max_restarts:
                node.restarts += 1
                self.log(
                    f"{NodeDied(node.name, code)}; restarting it "
                    f"({node.restarts}/{self.max_restarts})"
                )
                self._spawn(node)
                continue
            node.popen = None
            extra = f" (after {node.restarts} restarts)" if node.restarts else ""
            raise NodeDied(node.name, code, extra)

    def stop(self, grace: float = 1.0) -> None:
        """SIGTERM every running child, SIGKILL what is left after ``grace`` seconds."""
        running = [n for n in self.nodes if n.popen is not None and n.popen.poll() is None]
        for n in running:
            n.popen.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + grace
        for n in running:
            try:
                n.popen.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                n.popen.kill()
                n.popen.wait()

    @property
    def restarts(self) -> dict[str, int]:
        return {n.name: n.restarts for n in self.nodes if n.restarts}
