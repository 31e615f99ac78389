"""compose.yaml and the Dockerfile, checked as far as possible without a Docker engine.

compose.yaml: it parses; the router runs the eclipse/zenoh image of exactly the
installed wheel's version, with an explicit tcp listen endpoint and multicast off; every
other service runs an existing console script with arguments its real parser accepts;
every Zenoh endpoint is an explicit tcp endpoint naming the router's service and port;
every onboard's serial URLs name its own simulator service and the ports it listens on.

Dockerfile: a Python base image that satisfies requires-python; it copies what
`pip install .` needs (and .dockerignore does not drop it), installs the project, and
runs every console script, each of which resolves to a callable.
"""

from __future__ import annotations

import argparse
import fnmatch
import importlib
import importlib.metadata
import re
import shlex
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import yaml

from fleet.transport.zenoh_config import CONNECT_ENV, make_config

REPO = Path(__file__).resolve().parent.parent
COMPOSE = yaml.safe_load((REPO / "compose.yaml").read_text())
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
SCRIPTS: dict[str, str] = PYPROJECT["project"]["scripts"]
SERVICES: dict[str, dict[str, Any]] = COMPOSE["services"]
ROUTER = "router"


def command_of(service: dict[str, Any]) -> list[str]:
    command = service.get("command", [])
    return shlex.split(command) if isinstance(command, str) else [str(c) for c in command]


def option(argv: list[str], name: str) -> str | None:
    """The value after `name` in `argv` (or of `name=value`), None if absent."""
    for i, arg in enumerate(argv):
        if arg == name and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith(name + "="):
            return arg.split("=", 1)[1]
    return None


def fleet_services() -> dict[str, dict[str, Any]]:
    return {name: s for name, s in SERVICES.items() if name != ROUTER}


@contextmanager
def accepted_by(parser: argparse.ArgumentParser, argv: list[str], where: str) -> Iterator[None]:
    try:
        parser.parse_args(argv)
    except SystemExit as error:  # argparse reports a refusal by exiting
        pytest.fail(f"{where}: {argv} refused by {parser.prog} (exit {error.code})")
    yield


def router_listen() -> tuple[str, int]:
    argv = command_of(SERVICES[ROUTER])
    listen = option(argv, "--listen") or option(argv, "-l")
    assert listen is not None, "the router has no explicit --listen endpoint"
    match = re.fullmatch(r"tcp/([^:]+):(\d+)", listen)
    assert match, f"router listen endpoint {listen!r} is not tcp/HOST:PORT"
    return match[1], int(match[2])


# ---- compose.yaml -----------------------------------------------------------------------
def test_router_pins_the_installed_zenoh_version() -> None:
    version = importlib.metadata.version("eclipse-zenoh")
    assert SERVICES[ROUTER]["image"] == f"eclipse/zenoh:{version}"


def test_router_listens_on_explicit_tcp_with_multicast_off() -> None:
    argv = command_of(SERVICES[ROUTER])
    host, port = router_listen()
    assert host == "0.0.0.0"  # reachable from the other containers
    assert "--no-multicast-scouting" in argv
    assert any(str(p).split(":")[-1] == str(port) for p in SERVICES[ROUTER].get("ports", []))


def test_the_router_port_is_published_on_this_host_only() -> None:
    for published in SERVICES[ROUTER].get("ports", []):
        assert str(published).startswith("127.0.0.1:"), published


def test_fleet_processes_have_multicast_off_in_code() -> None:
    # The fleet's services take no zenoh config file: make_config is their config.
    for mode in ("client", "peer", "router"):
        assert make_config(mode).get_json("scouting/multicast/enabled") == "false"


def test_there_is_a_ground_and_a_sim_and_onboard_per_uav() -> None:
    scripts = {name: command_of(s)[0] for name, s in fleet_services().items()}
    assert "ground-cli" in scripts.values()
    onboard_ids = {
        option(command_of(s), "--id")
        for n, s in fleet_services().items()
        if scripts[n] == "onboard"
    }
    sim_ids = {
        option(command_of(s), "--uav")
        for n, s in fleet_services().items()
        if command_of(s)[:2] == ["fleet", "sim"]
    }
    assert onboard_ids == sim_ids
    assert len(onboard_ids) >= 2  # the thesis's multi-UAV scenario


def test_every_fleet_service_is_built_from_this_project() -> None:
    for name, service in fleet_services().items():
        assert service.get("build") in (".", {"context": "."}), name
        assert service.get("image", "").startswith("uav-fleet:"), name


def test_every_command_names_an_existing_console_script() -> None:
    for name, service in fleet_services().items():
        argv = command_of(service)
        assert argv and argv[0] in SCRIPTS, f"{name}: {argv[:1]} is not one of {sorted(SCRIPTS)}"


def _parser_for(script: str) -> Callable[[], argparse.ArgumentParser]:
    if script == "onboard":
        from onboard.main import build_parser as onboard_parser

        return onboard_parser
    if script == "ground-cli":
        from ground.cli import build_parser as ground_parser

        return ground_parser
    from programs.fleet_cli import build_parser as fleet_parser

    return fleet_parser


def test_every_command_is_accepted_by_its_cli() -> None:
    unwired = []
    for name, service in fleet_services().items():
        argv = command_of(service)
        parser = _parser_for(argv[0])()
        if argv[0] == "fleet":
            choices = next(
                a.choices
                for a in parser._actions
                if isinstance(a, argparse._SubParsersAction) and a.choices is not None
            )
            if argv[1] not in choices:
                unwired.append(f"fleet {argv[1]}")
                continue
        with accepted_by(parser, argv[1:], name):
            pass
    assert not unwired, f"not wired into the fleet CLI: {', '.join(sorted(set(unwired)))}"


def test_zenoh_endpoints_are_explicit_tcp_to_the_router() -> None:
    _, port = router_listen()
    expected = f"tcp/{ROUTER}:{port}"
    for name, service in fleet_services().items():
        assert service.get("environment", {}).get(CONNECT_ENV) == expected, name
        argv = command_of(service)
        if argv[0] in ("onboard", "ground-cli"):
            assert option(argv, "--connect") == expected, name
        if argv[0] == "onboard":
            assert option(argv, "--mode") == "client", name  # the star: routed by the router


def test_each_onboard_talks_to_its_own_simulator() -> None:
    sims = {
        option(command_of(s), "--uav"): (name, command_of(s))
        for name, s in fleet_services().items()
        if command_of(s)[:2] == ["fleet", "sim"]
    }
    for name, service in fleet_services().items():
        argv = command_of(service)
        if argv[0] != "onboard":
            continue
        uav = option(argv, "--id")
        sim_name, sim_argv = sims[uav]
        assert option(sim_argv, "--host") == "0.0.0.0", sim_name
        for port_option, url_option in (
            ("--program-port", "--program"),
            ("--payload-port", "--payload"),
        ):
            url = f"socket://{sim_name}:{option(sim_argv, port_option)}"
            assert option(argv, url_option) == url, name
        assert {ROUTER, sim_name} <= set(service.get("depends_on", [])), name


def test_each_simulated_uav_is_in_its_scenario() -> None:
    from fleet.sim.scenario import resolve_scenario

    for name, service in fleet_services().items():
        argv = command_of(service)
        if argv[:2] == ["fleet", "sim"]:
            uav = option(argv, "--uav")
            assert uav is not None, name
            resolve_scenario(argv[2]).uav(int(uav))  # raises if the id is not in it


# ---- Dockerfile ---------------------------------------------------------------------------
def dockerfile() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) pairs, continuation lines joined, comments dropped."""
    text = (REPO / "Dockerfile").read_text()
    lines: list[str] = []
    pending = ""
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        lines.append(pending + line)
        pending = ""
    return [(line.split(None, 1)[0].upper(), line.split(None, 1)[1]) for line in lines]


def dockerignored(path: str) -> bool:
    patterns = [
        p.strip()
        for p in (REPO / ".dockerignore").read_text().splitlines()
        if p.strip() and not p.startswith("#")
    ]
    parts = Path(path).parts
    return any(
        fnmatch.fnmatch(path, pattern)
        or fnmatch.fnmatch(parts[0], pattern)
        or fnmatch.fnmatch(path, pattern.removeprefix("**/"))
        for pattern in patterns
    )


def test_dockerfile_base_image_satisfies_requires_python() -> None:
    base = next(args for op, args in dockerfile() if op == "FROM")
    match = re.fullmatch(r"python:(\d+)\.(\d+)(?:[.-]\S*)?", base.split()[0])
    assert match, f"base image {base!r} is not an official python image"
    required = re.fullmatch(r">=(\d+)\.(\d+)", PYPROJECT["project"]["requires-python"])
    assert required
    assert (int(match[1]), int(match[2])) >= (int(required[1]), int(required[2]))


def test_dockerfile_copies_what_pip_install_needs() -> None:
    copied: set[str] = set()
    for op, args in dockerfile():
        if op == "COPY":
            *sources, _ = args.split()
            for source in sources:
                assert (REPO / source).exists(), f"COPY {source}: no such file"
                assert not dockerignored(source), f"COPY {source}: excluded by .dockerignore"
                copied.add(source.rstrip("/"))
    needed = {"pyproject.toml", PYPROJECT["project"]["readme"]}
    needed |= {
        p.rstrip("*") for p in PYPROJECT["tool"]["setuptools"]["packages"]["find"]["include"]
    }
    assert needed <= copied


def test_dockerfile_installs_the_project_and_runs_every_console_script() -> None:
    runs = " && ".join(args for op, args in dockerfile() if op == "RUN")
    assert re.search(r"pip install (--\S+ )*\.(\s|$)", runs), runs
    for script in SCRIPTS:
        assert f"{script} --help" in runs, f"the build does not try {script}"
    cmd = next(args for op, args in reversed(dockerfile()) if op == "CMD")
    assert yaml.safe_load(cmd)[0] in SCRIPTS


def test_console_scripts_resolve_to_callables() -> None:
    for script, target in SCRIPTS.items():
        module, _, function = target.partition(":")
        assert callable(getattr(importlib.import_module(module), function)), script


# ---- compose.secure.yaml: the secure profile as an override -------------------------------
SECURE = yaml.safe_load((REPO / "compose.secure.yaml").read_text())["services"]
CERTS = "/certs"


def secure_command(name: str) -> list[str]:
    return command_of(SECURE[name])


def test_secure_override_names_only_existing_services_and_every_zenoh_client() -> None:
    assert set(SECURE) <= set(SERVICES)
    clients = {n for n, s in fleet_services().items() if command_of(s)[0] != "fleet"}
    assert clients <= {n for n, s in SECURE.items() if "command" in s}  # none left on tcp


def mounts(service: dict[str, Any]) -> dict[str, str]:
    """A service's bind mounts: where in the container -> which file of this host."""
    found = {}
    for volume in service.get("volumes", []):
        source, target, *mode = volume.split(":")
        assert mode == ["ro"], volume  # nothing the fleet's identities are in is writable
        found[target] = source
    return found


def identity_of(name: str) -> str | None:
    argv = secure_command(name)
    if name == ROUTER:
        return "router"
    if not argv:
        return None  # a simulator: no identity
    return f"uav-{option(argv, '--id')}" if argv[0] == "onboard" else "ground"


def test_each_service_sees_its_own_key_and_no_other() -> None:
    for name, service in SECURE.items():
        identity = identity_of(name)
        seen = mounts(service)
        assert all(source.startswith("./certs/") for source in seen.values()), name
        assert all(target == f"{CERTS}/{Path(s).name}" for target, s in seen.items()), name
        keys = {Path(s).name for s in seen.values() if s.endswith((".key", ".sign"))}
        if identity is None:
            assert seen == {}, name
            continue
        # Never ca.key, never another's key; each has its own signing key (the router
        # signs its answer about itself, `router/state`).
        own = {f"{identity}.key", f"{identity}.sign"}
        assert keys == own, name
        # Every process checks signatures (and the router revocations) by the roster.
        assert {f"{CERTS}/ca.pem", f"{CERTS}/signers.json", f"{CERTS}/{identity}.pem"} <= set(
            seen
        ), name
        # Every file its command names under /certs is there.
        named = {a for a in secure_command(name) if a.startswith(CERTS + "/")}
        assert named <= set(seen), name
    assert "./certs:/certs:ro" not in (REPO / "compose.secure.yaml").read_text()


def test_each_simulator_is_reachable_from_its_own_onboard_only() -> None:
    networks = yaml.safe_load((REPO / "compose.secure.yaml").read_text())["networks"]
    for name, service in fleet_services().items():
        argv = command_of(service)
        if argv[:2] != ["fleet", "sim"]:
            continue
        uav = option(argv, "--uav")
        link = f"link-{uav}"
        assert SECURE[name]["networks"] == [link], name
        assert networks[link] == {"internal": True}
        on_link = {n for n, s in SECURE.items() if link in s.get("networks", [])}
        assert on_link == {name, f"uav-{uav}"}, on_link


def test_secure_router_is_ours_with_mtls_and_acl_on_the_same_port() -> None:
    from fleet.transport.router import build_parser as router_parser

    argv = secure_command(ROUTER)
    assert argv[:3] == ["python", "-m", "fleet.transport.router"]
    assert SECURE[ROUTER]["image"].startswith("uav-fleet:")
    args = router_parser().parse_args(argv[3:])
    assert str(args.secure) == CERTS
    _, port = router_listen()
    assert args.listen == [f"tls/0.0.0.0:{port}"]
    assert "ports" not in SECURE[ROUTER]  # compose.yaml's, on 127.0.0.1 only


def test_each_secure_client_uses_its_own_identity_over_tls() -> None:
    _, port = router_listen()
    expected = f"tls/{ROUTER}:{port}"
    for name in SECURE:
        if name == ROUTER or "command" not in SECURE[name]:
            continue
        argv = secure_command(name)
        with accepted_by(_parser_for(argv[0])(), argv[1:], name):
            pass
        identity = f"uav-{option(argv, '--id')}" if argv[0] == "onboard" else "ground"
        assert option(argv, "--zenoh-config") == f"{CERTS}/{identity}.json5", name
        assert option(argv, "--connect") == expected, name
        assert SECURE[name]["environment"][CONNECT_ENV] == expected, name
        # Everything else is as in the open profile.
        open_argv = command_of(SERVICES[name])
        assert [a for a in argv if a not in (option(argv, "--zenoh-config"), "--zenoh-config")] == [
            a if a != option(open_argv, "--connect") else expected for a in open_argv
        ], name


def test_the_documented_certs_command_makes_every_file_the_profile_names(
    tmp_path: Path,
) -> None:
    from programs.fleet_cli import main as fleet_main

    header = (REPO / "compose.secure.yaml").read_text()
    line = next(line for line in header.splitlines() if "fleet certs make" in line)
    argv = shlex.split(line.lstrip("# "))[1:]
    argv[argv.index("certs", 2)] = str(tmp_path)  # DIR
    assert fleet_main(argv) == 0
    for name in SECURE:
        for arg in secure_command(name):
            if arg.startswith(CERTS + "/"):
                assert (tmp_path / arg.removeprefix(CERTS + "/")).is_file(), arg
    tls = yaml.safe_load((tmp_path / "uav-74.json5").read_text())["transport"]["link"]["tls"]
    assert tls["connect_certificate"] == f"{CERTS}/uav-74.pem"
