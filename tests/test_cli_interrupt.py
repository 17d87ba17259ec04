"""Ctrl-C during a command's start-up: exit code 130 and one line on stderr, never a traceback
from the package (before, an interrupt while `gyrodrift` imported numpy, scipy and the core
printed a 20-38 line KeyboardInterrupt trace).

The test does not depend on timing: it interrupts real `python -m gyrodrift` processes after
several delays spread over the start-up and the first second of work, and accepts for each
what can happen at that instant, whatever the machine's load:
- the interrupt was handled by the command: exit 130, exactly one line "gyrodrift[ CMD]:
  interrupted" (or the same line and the process ended by SIGINT, which a shell also shows
  as 130: CPython exits that way when a KeyboardInterrupt once passed through its
  PyRun_String machinery, as in an extension module's initialisation, even if caught);
- it came before the interpreter set up its own handler: killed by SIGINT, nothing printed
  (a shell shows this as 130 too);
- it came while CPython itself was starting (site, runpy), or while the package imported
  the module that installs its handler: CPython's own trace, with no frame of the package
  but that import (nothing can handle it there; the window is a few milliseconds);
- the command had already finished: exit 0.
A trace with a frame of the package fails, and so does a run in which no interrupt reached the
command's handler (the test would have checked nothing).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

DELAYS_S = (0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.1)


def _before_the_handler(err: str) -> bool:
    """No trace, or one whose frames of the package are only the import of its start-up
    module, which installs the handler (the interrupt came before it could)."""
    if "Traceback" not in err:
        return True
    lines = err.splitlines()
    for i, line in enumerate(lines):
        if 'File "' in line and "/gyrodrift/" in line:
            code = lines[i + 1] if i + 1 < len(lines) else ""
            if line.split('"')[1].endswith("_startup.py") or "_startup" in code:
                continue
            return False
    return True


def _swallowed_by_cpython(err: str) -> bool:
    """CPython's own report of a KeyboardInterrupt raised in a callback it ignores the
    exceptions of (the interrupt is then lost and the program runs on)."""
    lines = err.strip().splitlines()
    return bool(lines) and lines[0].startswith("Exception ignored in") \
        and lines[-1].strip() == "KeyboardInterrupt:"


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("rec") / "r.npy"
    np.save(p, np.random.default_rng(0).normal(size=400_000))
    return p


def _interrupt(argv: list[str], delay_s: float) -> tuple[int, str]:
    proc = subprocess.Popen([sys.executable, "-m", "gyrodrift", *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=os.environ.copy())
    time.sleep(delay_s)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err.decode(errors="replace")


@pytest.mark.parametrize("command", ["allan", "characterize"])
def test_ctrl_c_during_start_up_is_one_line(record: Path, tmp_path: Path, command: str) -> None:
    argv = {"allan": ["allan", str(record), "--rate-hz", "100", "--gyro-units", "deg/h",
                      "--json"],
            "characterize": ["characterize", str(record), "--rate-hz", "100", "--gyro-units",
                             "rad/s", "--out-dir", str(tmp_path / "ch")]}[command]
    handled, finished = 0, False
    delays = list(DELAYS_S)
    while delays:
        delay_s = delays.pop(0)
        code, err = _interrupt(argv, delay_s)
        lines = err.strip().splitlines()
        where = f"{command} interrupted after {delay_s} s: exit {code}\n{err[-3000:]}"
        assert _before_the_handler(err), where
        if code in (130, -signal.SIGINT) and lines and "Traceback" not in err:
            assert len(lines) == 1 and lines[0].endswith("interrupted"), where
            assert lines[0].startswith("gyrodrift"), where
            handled += 1
        elif code == 0:
            # finished; CPython may have swallowed the interrupt in a callback it was running
            # (an import lock's weakref callback), which it reports as "Exception ignored"
            # with no frame of the package (checked above) and then runs on
            assert "Traceback" not in err or _swallowed_by_cpython(err), where
            finished = True
        else:
            # Before the package's code ran: killed by the default disposition, or CPython's
            # own start-up trace (no frame of the package: checked above). CPython ends by
            # SIGINT after printing that trace, so exit -2 with a trace is this case too.
            assert code in (-signal.SIGINT, 1), where
            assert not lines or "Traceback" in err, where
        if not delays and handled < 3 and not finished and delay_s < 30.0:
            # A loaded machine (a parallel test run) can take longer than the spread above to
            # start: interrupt later until three reach the command, or it ends first.
            delays.append(delay_s * 1.5)
    assert handled >= 3, f"only {handled} interrupts reached the command"


@pytest.mark.parametrize("argv0", [None, "-m"])
def test_other_programs_keep_their_ctrl_c(argv0: str | None) -> None:
    """Only the `gyrodrift` command itself gets the start-up handler: a program importing
    the package keeps Python's own handling, also while sys.argv[0] is "-m" (as during
    `python -m` of another module that imports the package)."""
    code = ("import signal, sys\n"
            + ("" if argv0 is None else f"sys.argv[0] = {argv0!r}\n")
            + "import gyrodrift\n"
            "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=os.environ.copy(), timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip().splitlines()[-1] == "True"
