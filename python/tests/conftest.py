"""Shared fixtures of the pytest suite of `import lucent` (run by `make test`)."""

import os
import signal
import subprocess
import threading
from pathlib import Path

import pytest

# miepython's pure-numpy backend: no numba compilation in the tests, and the
# backend tools/reference/ generates its data with.
os.environ.setdefault("MIEPYTHON_USE_JIT", "0")

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture
def ctrl_c():
    """`ctrl_c(delay_s)` sends this process SIGINT after delay_s seconds, as
    Ctrl-C would, with Python's own handler installed for the test: a process
    started in the background by a non-interactive shell inherits SIGINT
    ignored, and Python then never raises KeyboardInterrupt."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timers = []

    def arm(delay_s: float) -> None:
        timers.append(threading.Timer(delay_s, lambda: os.kill(os.getpid(), signal.SIGINT)))
        timers[-1].start()

    yield arm
    for t in timers:
        t.cancel()
    signal.signal(signal.SIGINT, previous)


@pytest.fixture(scope="session")
def lucent_cli() -> Path:
    """The `lucent` command of this checkout: $LUCENT_BIN, else the debug build
    `cargo test --workspace` leaves in target/ (`make test` runs that first),
    else built here."""
    if "LUCENT_BIN" in os.environ:
        exe = Path(os.environ["LUCENT_BIN"])
    else:
        target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
        exe = target / "debug" / "lucent"
        if not exe.exists():
            subprocess.run(["cargo", "build", "--quiet", "--bin", "lucent"], cwd=REPO, check=True)
    assert exe.exists(), exe
    return exe


def run_cli(exe: Path, *args, cwd=None) -> subprocess.CompletedProcess:
    """Runs the lucent command; fails the test with its stderr on a non-zero exit."""
    p = subprocess.run([str(exe), *map(str, args)], cwd=cwd, capture_output=True, text=True)
    assert p.returncode == 0, f"lucent {' '.join(map(str, args))} failed:\n{p.stderr}"
    return p
