"""Run a snippet in a fresh interpreter, so that a crash (segfault, abort) or a hang of the code
under test is a failed assertion instead of the end of the test run."""

import os
import subprocess
import sys
import textwrap


def run_isolated(code: str, timeout: float = 120, args=()) -> subprocess.CompletedProcess:
    """``python -c code args...`` with this interpreter and environment; rc -11 is a segfault,
    -6 an abort; raises subprocess.TimeoutExpired past ``timeout`` seconds."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, env=dict(os.environ))


def outcome(code: str, timeout: float = 120, args=()) -> str:
    """The snippet's last stdout line when it exits 0; otherwise a description of how it ended
    (a test then fails with it in the assertion message)."""
    try:
        p = run_isolated(code, timeout, args)
    except subprocess.TimeoutExpired:
        return f"HANG: still running after {timeout} s"
    if p.returncode != 0:
        return f"CRASH rc={p.returncode}: {p.stderr[-600:]}"
    lines = p.stdout.strip().splitlines()
    return lines[-1] if lines else ""
