"""Linux network namespaces for the tests and benchmarks that need hosts really apart:
`ip` (iproute2) run and checked, and whether this machine allows namespaces at all."""

from __future__ import annotations

import os
import shutil
import subprocess


def ip(*argv: str) -> subprocess.CompletedProcess[str]:
    """`ip ARGV`, its output captured, never raising on a failure (`check_ip` does)."""
    return subprocess.run(["ip", *argv], capture_output=True, text=True, check=False)


def check_ip(done: subprocess.CompletedProcess[str]) -> None:
    """Fail, naming the command and what `ip` said, unless it succeeded."""
    assert done.returncode == 0, f"{done.args}: {done.stderr}"


def namespaces_allowed(tag: str) -> str | None:
    """None if this machine lets us make namespaces, else why not (`tag`: a unique prefix
    for the probe namespace's name)."""
    if shutil.which("ip") is None:
        return "no `ip` command (iproute2)"
    if os.geteuid() != 0:
        return "network namespaces need root"
    probe = f"{tag}-probe"
    made = ip("netns", "add", probe)
    if made.returncode != 0:
        return f"`ip netns add` refused: {made.stderr.strip()}"
    ip("netns", "del", probe)
    return None


def in_namespace(namespace: str, *argv: str) -> list[str]:
    """`argv` run inside `namespace` (`ip netns exec` execs it: the PID is argv's own)."""
    return ["ip", "netns", "exec", namespace, *argv]
