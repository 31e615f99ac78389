"""Start and stop a whole simulated fleet on one machine: router, simulator, onboards.

What runs (one machine, the star of docs/architecture.md):

* the Zenoh router, embedded in this process (`fleet.transport.router`), listening on `listen`
  (on port 0: a port the OS picks, which `Fleet.listening` then says);
* one `fleet sim SCENARIO` process simulating every aircraft of the scenario on free
  ports (one process rather than one per UAV: the simulator serves many aircraft from
  one selector loop, and one process is half the memory of N);
* one `onboard` process per UAV, a Zenoh client of the router, on the program and
  payload ports the simulator printed (`fleet.launch.endpoints`), forked from a fork
  server that imported the onboard program once (`fleet.launch.fork_client`);
* unless told not to, a recorder (`fleet.recording`), started first, so the whole run
  is recorded into `record` (an MCAP file): in this process on the router's own session
  (one process and one hop fewer for every sample), or, in a router-per-UAV
  mesh, one `fleet record` process, a client that can fall back to any router.

Children are started with `sys.executable -m ...` (no dependence on console scripts
being on PATH), in their own session (process group), so a Ctrl-C in the terminal
reaches only the launcher, which then stops them in order (onboards, then simulator)
by PID: SIGTERM, then SIGKILL after a grace period. Their output goes to one log file
each in `log_dir`. A launcher that dies without stopping them (SIGKILL, a crash) takes
them with it: each is bound to it by the kernel's parent-death signal
(`fleet.lifeline`), the fork server's children to the fork server. They must then be
started from the thread that lives as long as the fleet (the launcher's main thread).
A generated fleet's scenario (`--uavs N`) is `fleet.launch.ring`'s.
"""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Self

import zenoh

from fleet import lifeline
from fleet.errors import CertError, FleetError
from fleet.launch.children import STOP_GRACE_S, Child, ChildProcess, stop_children
from fleet.launch.endpoints import (
    SimEndpoints,
    client_endpoint,
    free_port,
    host_port,
    parse_sim_line,
)
from fleet.launch.fork_client import ForkServer, ForkServerError
from fleet.launch.holders import port_holders, uav_holders
from fleet.launch.topology import Topology, fallbacks, ring_links
from fleet.mission.access import ROUTER, uav_router_identity
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace, uav_id_of
from fleet.piccolo.telemetry import Telemetry
from fleet.recording.recorder import READY_LINE, Recorder
from fleet.recording.writer import McapSink
from fleet.sim.flight_model import Dynamics
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusSample, Declaration, decode_sample
from fleet.transport.bus_factory import open_bus
from fleet.transport.cli import CRASH_DUMP_ENV, PREFIX_ENV
from fleet.transport.router import Router, parse_listening
from fleet.transport.secure import SecureProfile
from fleet.transport.zenoh_bus import BusConnectError, ZenohBus
from fleet.transport.zenoh_config import CONNECT_ENV, DEFAULT_ROUTER, build_config, make_config

log = logging.getLogger(__name__)

#: Seconds to wait for the simulator's ports and every UAV's token and telemetry: dozens
#: of Python processes starting at once take seconds each on a busy machine.
DEFAULT_START_TIMEOUT_S = 120.0
#: At most one progress report this often while waiting for the UAVs, seconds.
PROGRESS_PERIOD_S = 1.0


class LaunchError(FleetError, RuntimeError):
    """The fleet could not be started; the message says which part and why."""


@dataclass
class FleetSpec:
    """What to launch. `scenario` is a shipped scenario name or a TOML path."""

    scenario: str
    listen: str = DEFAULT_ROUTER
    speedup: float = 1.0
    telemetry_hz: float | None = None
    log_dir: Path | None = None
    start_timeout_s: float = DEFAULT_START_TIMEOUT_S
    onboard_args: tuple[str, ...] = ()
    python: str = sys.executable
    #: The secure profile's identities (`fleet certs make`): mTLS and access control.
    secure_dir: Path | None = None
    #: One router (the ground's) or a router per UAV (fleet.launch.topology).
    topology: Topology = Topology.STAR
    #: How to run one UAV's onboard module after `python` (another build of it, say); a
    #: library setting, not a `fleet up` flag.
    onboard_command: tuple[str, ...] = ("-m", "onboard.main")
    #: Where `fleet record` writes the run's recording; None: not recorded.
    record: Path | None = None
    #: The fleet's keys: the router's access policy, the start's watch, and every child's
    #: (handed down in $FLEET_KEY_PREFIX).
    key_space: KeySpace = DEFAULT_SPACE
    #: Fork the onboards from one process that imported them (fleet.launch.fork_server):
    #: their imported pages are shared. False: each is its own `python -m`.
    fork_onboards: bool = True
    #: The simulated aircraft's flight model (`fleet sim --dynamics`).
    dynamics: Dynamics = Dynamics.KINEMATIC
    #: UAVs whose onboard proposes plans (`fleet-onboard --propose`).
    proposers: frozenset[int] = frozenset()


@dataclass
class Fleet:
    """A running fleet; a context manager that stops everything on exit.

    `stop_requested` (an Event) aborts a start in progress, e.g. from a signal handler.
    """

    spec: FleetSpec
    stop_requested: threading.Event = field(default_factory=threading.Event)
    #: Told how the start is going ("12 of 50 UAVs ready"), from the starting thread.
    progress: Callable[[str], None] | None = None
    endpoints: list[SimEndpoints] = field(default_factory=list)
    children: list[Child] = field(default_factory=list)
    router: Router | None = None
    secure: SecureProfile | None = None
    #: The recorder in this process (a star's), while the fleet runs.
    recorder: Recorder | None = None
    #: Why the in-process recording stopped before the fleet did (a full disk, ...).
    recording_failure: str | None = None
    #: Telemetry samples the in-process recorder wrote per UAV, once the fleet stopped:
    #: from the moment every UAV flew to the start of the stop (`StreamCounts.telemetry`).
    recorded_telemetry: dict[int, int] = field(default_factory=dict)
    #: The routers of a router-per-uav mesh: UAV id -> the endpoint clients connect to.
    uav_routers: dict[int, str] = field(default_factory=dict)
    #: The ground's router's endpoint with the port it bound (`spec.listen` may ask for
    #: port 0), once it listens.
    listening: str | None = None
    #: What forks the onboards, while the fleet runs (`FleetSpec.fork_onboards`).
    fork_server: ForkServer | None = None
    #: Opens the bus a start is watched through when no router runs in this process (a
    #: mesh): the program's root hands its factory down.
    open_bus: Callable[[zenoh.Config], Bus] = open_bus
    log_dir: Path = field(init=False)
    _sim_ready: threading.Event = field(default_factory=threading.Event)
    _files: list[IO[bytes]] = field(default_factory=list)
    _readers: list[threading.Thread] = field(default_factory=list)
    _watch: _ReadyWatch | None = None

    def __post_init__(self) -> None:
        if self.spec.log_dir is not None:
            self.spec.log_dir.mkdir(parents=True, exist_ok=True)
            self.log_dir = self.spec.log_dir
        else:
            self.log_dir = Path(tempfile.mkdtemp(prefix="fleet-"))

    @property
    def connect(self) -> str:
        """The endpoint a ground client on this machine connects to (once the router
        listens, on the port it bound)."""
        return client_endpoint(self.listening or self.spec.listen)

    @property
    def fallback_connect(self) -> list[str]:
        """Every router a ground client can use, the ground's first."""
        return [self.connect, *self.uav_routers.values()]

    @property
    def uav_ids(self) -> list[int]:
        return [e.piccolo_id for e in self.endpoints]

    def __enter__(self) -> Self:
        try:
            self.start()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    # ---- starting -------------------------------------------------------------------
    def start(self) -> None:
        deadline = time.monotonic() + self.spec.start_timeout_s
        self._refuse_held_port()
        try:
            self.secure = self._secure_profile()
            if self.spec.topology is Topology.STAR:
                self.router = Router([self.spec.listen], secure=self.secure)
                self.router.open()
                self.listening = self.router.endpoints[0]
        except Exception as error:
            raise LaunchError(str(error)) from error
        # It imports while the simulator starts.
        self._start_fork_server()
        # The recorder starts before the onboards, the first to put anything on the bus;
        # in a mesh, once every router is up, so it can fall back to any of them.
        if self.spec.topology is Topology.STAR:
            self._start_recorder(deadline)
        else:
            # Its own process, so it can die (or be killed) without the launcher.
            self.listening = self._start_router("router-ground", self.spec.listen, [], deadline)
        self._start_sim(deadline)
        self._refuse_held_uavs()
        self._report(f"simulator up with {len(self.endpoints)} aircraft; starting their onboards")
        if self.spec.topology is Topology.ROUTER_PER_UAV:
            self._start_uav_routers(deadline)
            self._start_recorder(deadline)
        if self.fork_server is not None:
            try:
                self.fork_server.wait_ready(max(0.0, deadline - time.monotonic()))
            except ForkServerError as error:
                raise LaunchError(f"{error}; see {self.log_dir / 'fork-server.log'}") from None
        self._watch_start()
        for endpoints in self.endpoints:
            self._start_onboard(endpoints)
        self._write_pids()
        self._wait_ready(deadline)

    def _refuse_held_port(self) -> None:
        """LaunchError naming the processes that listen on the router's port (none can on
        port 0: the OS gives a free one)."""
        port = host_port(self.connect)[1]
        holders = port_holders(port) if port != 0 else []
        if holders:
            raise LaunchError(
                f"port {port} of {self.spec.listen} is held by "
                f"{'; '.join(map(str, holders))}: stop it, or give another --listen"
            )

    def _refuse_held_uavs(self) -> None:
        """LaunchError naming the onboards of other fleets that would join this one with
        its Piccolo IDs (they connect to its router's port)."""
        port = host_port(self.connect)[1]
        holders = uav_holders(port, self.uav_ids)
        if holders:
            raise LaunchError(
                f"UAV {', '.join(map(str, self.uav_ids))}: onboard modules of another fleet "
                f"would join this one on port {port}: {'; '.join(map(str, holders))}; stop them"
            )

    def _start_router(
        self, name: str, listen: str, connect: list[str], deadline: float, identity: str = ROUTER
    ) -> str:
        """Start a router process listening on `listen`; the endpoint it printed once it
        listens (on the port it bound, when `listen` asks for port 0)."""
        argv = [self.spec.python, "-m", "fleet.transport.router", "--listen", listen]
        for endpoint in connect:
            argv += ["--connect", endpoint]
        if self.secure is not None:
            # A UAV's router presents its own identity, scoped to that UAV.
            try:
                self.secure.identity(identity).check()
            except CertError as error:
                raise LaunchError(f"{name} has no identity: {error}") from None
            argv += ["--secure", str(self.secure.directory), "--identity", identity]
        log_path = self.log_dir / f"{name}.log"
        # The log is appended to (a --log-dir used again): only what this one prints.
        start = log_path.stat().st_size if log_path.exists() else 0
        child = self._spawn(name, argv)
        child.essential = False
        while (bound := _first_in_log(log_path, start, parse_listening)) is None:
            self._check_running(deadline, f"{name} to listen on {listen}")
            time.sleep(0.05)
        # Restarted (`--restart`), it listens where its clients already dial, not on a
        # new free port.
        argv[argv.index("--listen") + 1] = bound
        child.argv = tuple(argv)
        return bound

    def _start_uav_routers(self, deadline: float) -> None:
        proto = self.spec.listen.partition("/")[0]
        host = host_port(self.connect)[0]
        for uav in self.uav_ids:
            # Guessed, not port 0: each router dials its ring neighbour, which must have an
            # endpoint before it starts (the ring is a cycle: one of them starts last), and
            # a restarted router must come back where its clients dial it.
            self.uav_routers[uav] = f"{proto}/{host}:{free_port(host)}"
        for uav, neighbours in ring_links(self.uav_ids).items():
            connect = [self.connect, *(self.uav_routers[n] for n in neighbours)]
            identity = uav_router_identity(uav)
            self._start_router(f"router-{uav}", self.uav_routers[uav], connect, deadline, identity)

    def _onboard_connect(self, uav: int) -> list[str]:
        if not self.uav_routers:
            return [self.connect]
        own_first = [self.uav_routers[u] for u in fallbacks(self.uav_ids, uav)]
        return [*own_first, self.connect]

    def _secure_profile(self) -> SecureProfile | None:
        if self.spec.secure_dir is None:
            return None
        if not self.spec.listen.startswith("tls/"):
            raise LaunchError(
                f"the secure profile listens on tls/ endpoints, not {self.spec.listen}"
            )
        return SecureProfile.load(self.spec.secure_dir, self.spec.key_space)

    def _child_env(self) -> dict[str, str]:
        # Each child ends with this process, however it dies (fleet.lifeline), and a
        # crash of one, even while it imports, leaves its traceback in its log. Every
        # child is told its endpoints: an operator's $FLEET_ZENOH_CONNECT (which overrides
        # a config file's) must not redirect it.
        inherited = {k: v for k, v in os.environ.items() if k != CONNECT_ENV}
        env = {**inherited, PREFIX_ENV: self.spec.key_space.prefix, CRASH_DUMP_ENV: "1"}
        return lifeline.child_env(env)

    def _onboard_module(self) -> str | None:
        """The module the onboards run (`-m MODULE`), None if they run otherwise."""
        command = self.spec.onboard_command
        return command[1] if len(command) == 2 and command[0] == "-m" else None

    def _start_fork_server(self) -> None:
        module = self._onboard_module()
        if not self.spec.fork_onboards or module is None:
            return
        log_path = self.log_dir / "fork-server.log"
        server = ForkServer.start(self.spec.python, [module], log_path, self._child_env())
        self.fork_server = server
        # A child like the others: stopped with them, in the pids file, and essential
        # (without it, no onboard could be restarted or its exit status known).
        self.children.append(Child("fork-server", server.process, log_path))
        log.info("started the fork server (pid %d) for %s", server.process.pid, module)

    def _forked(self, argv: list[str]) -> str | None:
        """The module to fork for `argv` (the fork server's), None to start it as a process."""
        server = self.fork_server
        if server is None or argv[:2] != [self.spec.python, "-m"] or len(argv) < 3:
            return None
        return argv[2] if argv[2] in server.modules else None

    def _spawn(self, name: str, argv: list[str], stdout: int | IO[bytes] | None = None) -> Child:
        log_path = self.log_dir / f"{name}.log"
        process: ChildProcess
        module = self._forked(argv) if stdout is None else None
        if module is not None:
            assert self.fork_server is not None
            try:
                process = self.fork_server.spawn(module, argv[3:], log_path, self._child_env())
            except ForkServerError as error:
                raise LaunchError(f"cannot start {name}: {error}") from None
        else:
            log_file = open(log_path, "ab")  # noqa: SIM115  # closed in stop()
            self._files.append(log_file)
            process = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                stdout=log_file if stdout is None else stdout,
                stderr=log_file,
                start_new_session=True,
                env=self._child_env(),
            )
        child = Child(name, process, log_path, argv=tuple(argv))
        self.children.append(child)
        log.info("started %s (pid %d): %s", name, process.pid, " ".join(argv[1:]))
        return child

    def _start_recorder(self, deadline: float) -> None:
        path = self.spec.record
        if path is None:
            return
        if self.router is not None:
            self._record_in_router(path)
            return
        recorder = self._spawn(
            "record",
            [
                self.spec.python,
                "-m",
                "fleet.recording.commands",
                "record",
                str(path),
                *self._ground_zenoh_args(),
            ],
        )
        # Its first line says it listens; what the fleet says before would be lost.
        while READY_LINE not in recorder.tail():
            self._check_running(deadline, "the recorder")
            time.sleep(0.1)

    def _record_in_router(self, path: Path) -> None:
        assert self.router is not None
        recorder = Recorder(
            # The router's own session, unsigned: everything heard is recorded as it is.
            ZenohBus(self.router.session),
            McapSink(path),
            key_space=self.spec.key_space,
            on_failure=threading.Event(),  # the fleet flies on; `stop` says why it ended
            in_router=True,
        )
        try:
            recorder.start()
        except OSError as error:
            raise LaunchError(f"cannot record to {path}: {error.strerror or error}") from None
        self.recorder = recorder

    def _ground_zenoh_args(self) -> list[str]:
        """A ground-side client's Zenoh flags: every router, and the ground's identity."""
        args = [arg for endpoint in self.fallback_connect for arg in ("--connect", endpoint)]
        if self.secure is not None:
            args += ["--zenoh-config", str(self.secure.ground_config())]
        return args

    def _start_sim(self, deadline: float) -> None:
        argv = [
            self.spec.python,
            "-m",
            "fleet.sim.command",
            self.spec.scenario,
            "--program-port",
            "0",
            "--payload-port",
            "0",
            "--ground-port",
            "0",
            "--speedup",
            f"{self.spec.speedup:g}",
        ]
        if self.spec.telemetry_hz is not None:
            argv += ["--telemetry-hz", f"{self.spec.telemetry_hz:g}"]
        if self.spec.dynamics is not Dynamics.KINEMATIC:
            argv += ["--dynamics", self.spec.dynamics.value]
        sim = self._spawn("sim", argv, stdout=subprocess.PIPE)
        reader = threading.Thread(target=self._read_sim, args=(sim,), daemon=True)
        self._readers.append(reader)
        reader.start()
        while not self._sim_ready.wait(0.2):
            self._check_running(deadline, "the simulator's ports")
        if not self.endpoints:
            # The output ended before any aircraft: the simulator is exiting; let it
            # finish so its status and last words can be reported.
            with contextlib.suppress(subprocess.TimeoutExpired):
                sim.process.wait(timeout=STOP_GRACE_S)
            raise LaunchError(
                f"the simulator listed no aircraft (status {sim.process.returncode}); "
                f"last lines of {sim.log_path}:\n{sim.tail()}"
            )

    def _read_sim(self, sim: Child) -> None:
        # The simulator prints its ports, then `ready`, then nothing we need: everything
        # is copied to its log, and the pipe is drained until it closes so the
        # simulator can never block on a full pipe.
        assert sim.process.stdout is not None
        with open(sim.log_path, "ab") as copy:
            for raw in sim.process.stdout:
                copy.write(raw)
                copy.flush()
                line = raw.decode(errors="replace").strip()
                endpoints = parse_sim_line(line)
                if endpoints is not None and not self._sim_ready.is_set():
                    self.endpoints.append(endpoints)
                elif line == "ready":
                    self._sim_ready.set()
        self._sim_ready.set()  # the simulator exited: stop waiting, _check_running says why

    def _start_onboard(self, endpoints: SimEndpoints) -> None:
        zenoh_args: list[str] = []
        for endpoint in self._onboard_connect(endpoints.piccolo_id):
            zenoh_args += ["--connect", endpoint]
        if self.secure is not None:
            try:
                zenoh_args += ["--zenoh-config", str(self.secure.uav_config(endpoints.piccolo_id))]
            except CertError as error:
                raise LaunchError(f"UAV {endpoints.piccolo_id} has no identity: {error}") from None
        child = self._spawn(
            f"onboard-{endpoints.piccolo_id}",
            [
                self.spec.python,
                *self.spec.onboard_command,
                "--id",
                str(endpoints.piccolo_id),
                "--program",
                endpoints.program,
                "--payload",
                endpoints.payload,
                "--mode",
                "client",
                *zenoh_args,
                *(["--propose"] if endpoints.piccolo_id in self.spec.proposers else []),
                *self.spec.onboard_args,
            ],
        )
        # A UAV lost is one the team re-plans around, as with a container per UAV.
        child.essential = False

    def start_gui(self, listen: str) -> tuple[Child, str]:
        """Serve the Mission Manager's page (`ground-cli gui`) on `listen` (HOST:PORT; port
        0: a free one); the child and the page's URL it printed once it serves.

        A child process like the others (stopped with them, in the pids file): fleet/
        never imports the ground; it runs it.
        """
        argv = [self.spec.python, "-m", "ground.cli", *self._ground_zenoh_args()]
        log_path = self.log_dir / "gui.log"
        start = log_path.stat().st_size if log_path.exists() else 0
        child = self._spawn("gui", [*argv, "gui", "--listen", listen])
        self._write_pids()
        deadline = time.monotonic() + self.spec.start_timeout_s
        while (url := _first_in_log(log_path, start, _serving_url)) is None:
            self._check_running(deadline, f"the page to be served on {listen}")
            time.sleep(0.05)
        return child, url

    def restart(self, child: Child) -> Child:
        """Start `child` again with its own command; it takes the dead one's place."""
        if child.process.poll() is None or not child.argv:
            raise LaunchError(f"{child.name} is running or cannot be restarted")
        index = self.children.index(child)
        self.children.remove(child)
        again = self._spawn(child.name, list(child.argv))
        again.essential = child.essential
        self.children.remove(again)
        self.children.insert(index, again)
        self._write_pids()
        return again

    def _write_pids(self) -> None:
        lines = [f"{child.pid} {child.name}" for child in self.children]
        (self.log_dir / "pids").write_text("\n".join(lines) + "\n")

    def _check_running(self, deadline: float, waiting_for: str) -> None:
        dead = self.dead_children()
        if dead:
            child = dead[0]
            raise LaunchError(
                f"{child.name} exited with status {child.process.returncode} while waiting "
                f"for {waiting_for}; last lines of {child.log_path}:\n{child.tail()}"
            )
        if self.stop_requested.is_set():
            raise LaunchError("stopped on request while starting")
        if time.monotonic() > deadline:
            raise LaunchError(
                f"timed out after {self.spec.start_timeout_s:g} s waiting for {waiting_for} "
                f"(logs in {self.log_dir})"
            )

    def _observer(self) -> Bus:
        """A bus that sees the fleet's key space: the embedded router's session (not
        closed with it), or a client of the fleet's routers (`Fleet.open_bus`)."""
        if self.router is not None:
            return self.router.bus()
        config = make_config("client", self.fallback_connect)
        if self.secure is not None:
            config = build_config(
                config_file=str(self.secure.ground_config()), connect=self.fallback_connect
            )
        try:
            return self.open_bus(config)
        except BusConnectError as error:
            raise LaunchError(f"cannot watch the fleet start: {error}") from None

    def _watch_start(self) -> None:
        """Watch every UAV's token and telemetry, from before the first onboard starts.

        On the router's own session the watch stays declared until the fleet stops:
        Zenoh 1.10 loses the subscribers a client's declared publisher matches when a
        subscriber on the router's session is undeclared while that publisher is being
        declared (its telemetry then reaches nobody, while its other keys flow;
        `bench/zenoh_write_filter.py` reproduces it). An onboard declares its telemetry
        publisher as its link comes up, which is when a start-up watch would end.
        """
        bus = self._observer()
        watch = self._watch = _ReadyWatch(bus)
        watch.declarations = [bus.subscribe_presence(self.spec.key_space.all_alive, watch.on_token)]
        if self.router is not None:
            # Kept for the fleet's life: the telemetry waits in a ring Zenoh keeps, read by
            # `_wait_ready`, so no Python runs on the router's threads per sample after.
            ring = self.router.session.declare_subscriber(
                self.spec.key_space.all_telemetry,
                zenoh.handlers.RingChannel(4 * len(self.uav_ids) + 16),
            )
            watch.ring = ring
            watch.declarations.append(ring)
        else:
            watch.declarations.append(
                bus.subscribe(self.spec.key_space.all_telemetry, watch.on_telemetry)
            )

    def _watch_end(self) -> None:
        watch, self._watch = self._watch, None
        if watch is not None:
            watch.close()

    def _wait_ready(self, deadline: float) -> None:
        """Wait until every UAV is alive and its telemetry flows.

        A liveliness token only says the onboard process joined Zenoh; its serial link
        may not be up yet. A telemetry sample with a GPS fix on its telemetry key means
        the link is up and the autopilot talks, so its state already holds a position.
        """
        watch = self._watch
        assert watch is not None, "the watch starts before the onboards"
        expected = set(self.uav_ids)
        reported, next_report = (-1, -1), 0.0
        while not expected <= watch.alive & watch.flowing:
            watch.changed.wait(0.2)
            watch.drain()
            watch.changed.clear()
            alive, flowing = set(watch.alive), set(watch.flowing)
            counts = (len(expected & alive), len(expected & alive & flowing))
            if counts != reported and time.monotonic() >= next_report:
                self._report(
                    f"{counts[0]} of {len(expected)} UAVs alive, {counts[1]} with telemetry"
                )
                reported, next_report = counts, time.monotonic() + PROGRESS_PERIOD_S
            self._check_running(deadline, _waiting_for(expected, alive, flowing))
        log.info("every UAV is alive with telemetry: %s", ", ".join(map(str, sorted(expected))))
        if self.recorder is not None:
            self.recorder.streams.open_window()
        if self.router is None:  # a client's: its end is harmless
            self._watch_end()

    def _report(self, text: str) -> None:
        # Said once: to the progress callback (`fleet up` prints it), else to the log.
        if self.progress is not None:
            self.progress(text)
        else:
            log.info("%s", text)

    # ---- running and stopping ----------------------------------------------------------
    def dead_children(self, essential_only: bool = False) -> list[Child]:
        return [
            child
            for child in self.children
            if child.process.poll() is not None and (child.essential or not essential_only)
        ]

    def stop(self) -> None:
        """Stop every child (onboards first), then the router. Idempotent."""
        onboards = [c for c in self.children if c.name.startswith("onboard-")]
        others = [c for c in self.children if c not in onboards]
        if self.recorder is not None:
            self.recorder.streams.close_window()
        stop_children(onboards)
        stop_children(others)
        self._watch_end()
        # The simulator's output reader ends at EOF, now that the simulator has exited.
        for reader in self._readers:
            reader.join(timeout=STOP_GRACE_S)
        self._readers.clear()
        for child in self.children:
            if child.process.stdout is not None:
                child.process.stdout.close()
        for f in self._files:
            f.close()
        self._files.clear()
        if self.fork_server is not None:
            self.fork_server.close()
            self.fork_server = None
        if self.recorder is not None:
            self.recorder.stop()
            self.recording_failure = self.recorder.failure
            self.recorded_telemetry = self.recorder.streams.telemetry()
            self.recorder = None
        if self.router is not None:
            self.router.close()
            self.router = None


@dataclass
class _ReadyWatch:
    """Which UAVs' tokens and telemetry with a GPS fix were seen (on Zenoh's threads)."""

    bus: Bus
    alive: set[int] = field(default_factory=set)
    flowing: set[int] = field(default_factory=set)
    changed: threading.Event = field(default_factory=threading.Event)
    declarations: list[Declaration] = field(default_factory=list)
    ring: zenoh.Subscriber[Any] | None = None

    def drain(self) -> None:
        """The telemetry the ring holds (on the router's session), seen now."""
        ring = self.ring
        while ring is not None and (sample := ring.try_recv()) is not None:
            uav = _uav_of(str(sample.key_expr))
            if uav is None or uav in self.flowing:
                continue
            try:
                telemetry = bus_codec.decode(
                    sample.payload.to_bytes(), Telemetry, str(sample.key_expr)
                )
            except bus_codec.BadMessage:
                continue
            if telemetry.gps is not None:
                self.flowing.add(uav)

    def on_token(self, key: str, present: bool) -> None:
        uav = _uav_of(key)
        if uav is None:
            return
        if present:
            self.alive.add(uav)
        else:
            self.alive.discard(uav)
        self.changed.set()

    def on_telemetry(self, sample: BusSample) -> None:
        uav = _uav_of(sample.key)
        if uav is None or uav in self.flowing:
            return
        telemetry = decode_sample(sample, Telemetry)
        if telemetry is not None and telemetry.gps is not None:
            self.flowing.add(uav)
            self.changed.set()

    def close(self) -> None:
        for declaration in self.declarations:
            with contextlib.suppress(zenoh.ZError):  # the session closed already
                declaration.undeclare()
        self.declarations.clear()
        self.bus.close()  # the router's session stays open (Router.bus)


#: How `ground-cli gui` says where it serves the page: `gui: serving on URL [...]`.
GUI_SERVING = "gui: serving on "


def _serving_url(line: str) -> str | None:
    """The URL of a `gui: serving on URL` line; None for any other line."""
    rest = line.removeprefix(GUI_SERVING)
    return rest.split()[0] if rest != line and rest.strip() else None


def _first_in_log(log_path: Path, start: int, parse: Callable[[str], str | None]) -> str | None:
    """The first of a child's log lines after byte `start` that `parse` reads (what it
    read), or None yet (a child prints where it listens there once it does)."""
    try:
        with open(log_path, "rb") as log_file:
            log_file.seek(start)
            text = log_file.read().decode(errors="replace")
    except OSError:
        return None
    for line in text.split("\n")[:-1]:  # whole lines only: the last may be half written
        found = parse(line.strip())
        if found is not None:
            return found
    return None


def _uav_of(key: str) -> int | None:
    try:
        return uav_id_of(key)
    except ValueError:
        return None


def _waiting_for(expected: set[int], alive: set[int], flowing: set[int]) -> str:
    """What a start still waits for, for a timeout message."""
    parts = []
    if expected - alive:
        parts.append(f"the liveliness of UAV {', '.join(map(str, sorted(expected - alive)))}")
    if expected - flowing:
        quiet = ", ".join(map(str, sorted(expected - flowing)))
        parts.append(f"telemetry with a GPS fix from UAV {quiet}")
    return " and ".join(parts) or "nothing"
