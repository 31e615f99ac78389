import sys
import threading
from pathlib import Path

import pytest

from onboard.native_thread import name_native_thread

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="kernel thread names: Linux")


def _kernel_name_of(thread_name: str) -> str:
    seen: list[str] = []

    def body() -> None:
        name_native_thread()
        comm = Path(f"/proc/self/task/{threading.get_native_id()}/comm")
        seen.append(comm.read_text().strip())

    thread = threading.Thread(target=body, name=thread_name)
    thread.start()
    thread.join(5.0)
    return seen[0]


def test_the_kernel_knows_the_thread_by_its_python_name() -> None:
    assert _kernel_name_of("planner") == "planner"


def test_a_long_name_keeps_the_kernels_first_15_bytes() -> None:
    assert _kernel_name_of("link-123456789012345") == "link-1234567890"
