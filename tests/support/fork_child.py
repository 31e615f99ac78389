"""A program for the fork server's tests (`python -m tests.support.fork_child MODE`).

It prints its arguments, its session and `$FORK_CHILD_SAY`, then: `exit N` exits with
status N; `wait` prints `waiting` and sleeps until a signal ends it; `raise` raises;
`segv` sets up logging as every program of the project does, then crashes (SIGSEGV).
"""

from __future__ import annotations

import faulthandler
import os
import sys
import time

from fleet.transport.cli import setup_logging

#: The longest a `wait` child lives, s: a test that forgets it still ends.
WAIT_LIMIT_S = 120.0


def main(argv: list[str]) -> int:
    print(f"argv {argv} session {os.getsid(0)} pid {os.getpid()}")
    print(f"say {os.environ.get('FORK_CHILD_SAY', '')}", flush=True)
    mode = argv[0] if argv else "exit"
    if mode == "raise":
        raise RuntimeError("the child's own error")
    if mode == "segv":
        setup_logging(0)
        faulthandler._sigsegv()  # type: ignore[attr-defined]
    if mode == "wait":
        print("waiting", flush=True)
        time.sleep(WAIT_LIMIT_S)
    return int(argv[1]) if mode == "exit" and len(argv) > 1 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
