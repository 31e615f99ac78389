"""`ground-cli gui`: the Mission Manager's page, served from the ground process.

One aiohttp application on one event loop:

* `GET /` and `/static/...`: the page (plain HTML, CSS and JavaScript shipped in the
  package: no CDN, no JavaScript library);
* `GET /ws`: one WebSocket per page, pushed the fleet snapshot (`ground.gui.snapshot`)
  at most `rate_hz` times a second, and taking the operator's commands
  (`ground.gui.commands`): each acknowledged as it is read and answered when done, on a
  task of its own, so the reader never waits on the fleet (`ground.gui.ledger`);
* `GET /api/fleet`: the live UAVs in the same JSON as `ground-cli uavs --json`
  (`UavView.to_json`, from the page's live `FleetView`);
* `GET /api/mission`: the followed mission as `ground-cli send-targets --json` reports it;
* `POST /api/targets/import?name=FILE` (the file's bytes) and
  `POST /api/targets/export?format=bin|csv|geojson` (a JSON list of targets): Load and
  Save Targets through `ground.targets_formats`;
* `POST /api/zones/import` and `/api/zones/export`: Load and Save no-fly zones as
  GeoJSON (`ground.gui.zones_api`).

The bus's callbacks run on its (Zenoh's) threads; they reach the loop only through
`loop.call_soon_threadsafe`. Blocking queries run in worker threads.

Access: the page can send missions and aborts to aircraft, so by default it listens on
loopback only. Listening anywhere else requires `--allow-remote` and a token (from a
file or the environment, never argv, never printed): every request must carry it (`?token=` or an
`Authorization: Bearer` header). In every case, so that a web page in the operator's
browser cannot drive the fleet (`ground.gui.access`):

* a request whose Host is not the bound address or `localhost` is refused (DNS
  rebinding: another site's name resolved to this address);
* a WebSocket upgrade from another origin is refused;
* a WebSocket must carry this server's session token, which only the page it serves
  holds (in the HTML and a SameSite=Strict cookie): commands arrive only on such sockets.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import logging
import threading
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

import msgspec
from aiohttp import WSCloseCode, WSMsgType, web

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusSample, decode_sample
from ground import targets_formats
from ground.alerts import StatusRecord
from ground.fleet_view import FleetView
from ground.gui import zones_api
from ground.gui.access import Access
from ground.gui.commands import (
    AddTargetsCommand,
    ChangeCommand,
    Command,
    CommandError,
    MissionDesk,
    RemoveTargetsCommand,
    Reply,
    change_reply,
    decode_command,
    execute,
    put_change_of,
)
from ground.gui.ledger import CommandLedger, Later
from ground.gui.snapshot import Coalescer, GuiModel

log = logging.getLogger(__name__)

STATIC_DIR = Path(str(files("ground.gui") / "static"))
#: How often the UAVs' states (module on/off, mission phase, target) are queried.
STATE_PERIOD_S = 1.0
#: Largest targets file accepted by Load (bytes): 100,000 targets.
MAX_UPLOAD = 2_400_000
#: The server pings each page this often and closes a socket with no pong within half
#: of it: long, as a loaded box's browser answers late, and a page whose socket closed
#: reconnects (and re-sends what was not answered) anyway.
HEARTBEAT_S = 30.0
TOKEN_COOKIE = "fleet_gui_token"
SESSION_COOKIE = "fleet_gui_session"
_targets_decoder = msgspec.json.Decoder(list[Target])

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


@dataclass(frozen=True)
class GuiConfig:
    host: str
    port: int
    token: str | None  #: required on every request when set
    rate_hz: float
    query_timeout_s: float
    key_space: KeySpace  #: the fleet's keys (--key-prefix)


class GuiServer:
    """The page's server over one bus; `run` serves until cancelled."""

    def __init__(self, bus: Bus, config: GuiConfig) -> None:
        self.bus = bus
        self.config = config
        self.space = config.key_space
        self.model = GuiModel()
        self.sockets: set[web.WebSocketResponse] = set()
        self.commands_refused = 0
        self.access = Access(config.host)
        self._view: FleetView | None = None
        self._desk: MissionDesk | None = None
        self._coalescer: Coalescer | None = None
        self._ledger: CommandLedger | None = None
        #: Answers being sent: held here so that no task is collected before it ran.
        self._answers: set[asyncio.Task[None]] = set()
        #: Set when the server stops: a change waiting for acknowledgements stops waiting.
        self._stopping = threading.Event()

    # ---- set-up ------------------------------------------------------------------------
    def app(self) -> web.Application:
        app = web.Application(middlewares=[self._guard], client_max_size=MAX_UPLOAD)
        app.router.add_get("/", self._index)
        app.router.add_static("/static", STATIC_DIR)
        app.router.add_get("/ws", self._websocket)
        app.router.add_get("/api/fleet", self._api_fleet)
        app.router.add_get("/api/mission", self._api_mission)
        app.router.add_post("/api/targets/import", self._api_import)
        app.router.add_post("/api/targets/export", self._api_export)
        zones_api.add_routes(app)
        app.cleanup_ctx.append(self._fleet_context)
        app.on_shutdown.append(self._close_sockets)
        return app

    async def _close_sockets(self, app: web.Application) -> None:
        # On shutdown, before the server waits for its handlers to finish: an open page's
        # socket handler would otherwise hold the stop until its time-out.
        self._stopping.set()
        for ws in list(self.sockets):
            await ws.close(code=WSCloseCode.GOING_AWAY, message=b"server stopping")

    async def _fleet_context(self, app: web.Application) -> AsyncIterator[None]:
        loop = asyncio.get_running_loop()
        coalescer = self._coalescer = Coalescer(self._push, self.config.rate_hz)
        self._ledger = CommandLedger()

        def on_status(status: StatusRecord) -> None:  # a bus thread
            loop.call_soon_threadsafe(self._on_status, status)

        with contextlib.ExitStack() as stack:
            self._view = stack.enter_context(FleetView(self.bus, self.space, on_status))
            # Anything of the fleet changing wakes the pusher; the coalescer bounds the rate.
            everything = self.space.everything
            changes = self.bus.subscribe(everything, lambda _: coalescer.mark_threadsafe())
            stack.callback(changes.undeclare)
            tokens = self.bus.subscribe_presence(everything, lambda *_: coalescer.mark_threadsafe())
            stack.callback(tokens.undeclare)
            self._desk = MissionDesk(self.bus, self.space, coalescer.mark_threadsafe)
            stack.callback(self._desk.close)

            # A mission another ground sends is followed as soon as it is heard.
            def on_mission(sample: BusSample) -> None:  # a bus thread
                loop.call_soon_threadsafe(self._on_mission_targets, sample)

            missions = self.bus.subscribe(self.space.all_mission_targets, on_mission)
            stack.callback(missions.undeclare)
            tasks = [
                asyncio.create_task(coalescer.run()),
                asyncio.create_task(self._poll_states()),
            ]
            try:
                yield
            finally:
                for task in tasks:
                    task.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)

    def _on_mission_targets(self, sample: BusSample) -> None:
        message = decode_sample(sample, MissionTargets)
        desk = self._desk
        if message is None or desk is None:
            return
        followed = desk.mission
        if followed == message.mission:
            # The mission changed in flight (this page, or another ground).
            desk.revise(message)
        elif followed is None or message.mission > followed:
            task = asyncio.create_task(self._follow_later(desk, message))
            self._answers.add(task)
            task.add_done_callback(self._answers.discard)

    async def _follow_later(self, desk: MissionDesk, message: MissionTargets) -> None:
        try:
            await asyncio.to_thread(desk.follow_later, message, self.config.query_timeout_s)
        except Exception:
            log.exception("following mission %d failed", message.mission)

    def _on_status(self, status: StatusRecord) -> None:
        self.model.add_status(status)
        if self._coalescer is not None:
            self._coalescer.mark()

    async def _poll_states(self) -> None:
        """Query the states now and then; follow a newer mission another ground sent."""
        assert self._view is not None and self._desk is not None and self._coalescer
        while True:
            try:
                await asyncio.to_thread(self._view.refresh_states, self.config.query_timeout_s)
                missions = [v.mission for v in self._view.snapshot() if v.mission is not None]
                followed = self._desk.mission
                if missions and (followed is None or max(missions) > followed):
                    await asyncio.to_thread(
                        self._desk.adopt, max(missions), self.config.query_timeout_s
                    )
            except Exception:
                # The next round tries again; the page must keep being served.
                log.exception("querying the UAVs' states failed")
            self._coalescer.mark()
            await asyncio.sleep(STATE_PERIOD_S)

    # ---- access ------------------------------------------------------------------------
    @web.middleware
    async def _guard(self, request: web.Request, handler: Handler) -> web.StreamResponse:
        if not self.access.host_allowed(request.url.host):
            return self.access.refuse(request, 403, f"host {request.host!r} refused")
        token = self.config.token
        if token is not None:
            # The page's own URL carries the token; its stylesheet and script, loaded by
            # the browser, carry the cookie set then.
            given = request.query.get("token") or request.cookies.get(TOKEN_COOKIE, "")
            header = request.headers.get("Authorization", "")
            if header.startswith("Bearer "):
                given = header.removeprefix("Bearer ")
            if not hmac.compare_digest(given.encode(), token.encode()):
                return self.access.refuse(request, 401, "missing or wrong token")
        if request.path == "/ws":
            origin = request.headers.get("Origin")
            if origin is not None and origin.split("://", 1)[-1] != request.host:
                return self.access.refuse(request, 403, f"origin {origin} refused")
            session = request.query.get("session") or request.cookies.get(SESSION_COOKIE, "")
            if not self.access.session_matches(session):
                return self.access.refuse(request, 403, "missing or wrong session token")
        return await handler(request)

    # ---- pages and API -----------------------------------------------------------------
    async def _index(self, request: web.Request) -> web.StreamResponse:
        html = self.access.with_session((STATIC_DIR / "index.html").read_text())
        response = web.Response(text=html, content_type="text/html")
        response.headers["Cache-Control"] = "no-store"  # a token of this run only
        response.set_cookie(SESSION_COOKIE, self.access.session, httponly=True, samesite="Strict")
        if self.config.token is not None:
            response.set_cookie(TOKEN_COOKIE, self.config.token, httponly=True, samesite="Strict")
        return response

    async def _api_fleet(self, request: web.Request) -> web.Response:
        # The page's own live view (liveliness, telemetry and state subscriptions), in
        # `uavs --json`'s format: no query per request, and the same UAVs the map shows.
        assert self._view is not None
        return web.json_response([v.to_json() for v in self._view.snapshot()])

    async def _api_mission(self, request: web.Request) -> web.Response:
        outcome = self._desk.outcome() if self._desk is not None else None
        if outcome is None:
            return web.json_response({"error": "no mission followed yet"}, status=404)
        return web.json_response(outcome.to_json() | outcome.proposals_json())

    async def _api_import(self, request: web.Request) -> web.Response:
        name = request.query.get("name", "targets.bin")
        data = await request.read()
        try:
            targets = targets_formats.decode(data, name)
        except targets_formats.TargetsFormatError as error:
            return web.json_response({"error": f"{error}; nothing loaded"}, status=400)
        return web.json_response({"targets": [msgspec.to_builtins(t) for t in targets]})

    async def _api_export(self, request: web.Request) -> web.Response:
        try:
            fmt = targets_formats.TargetsFormat(request.query.get("format", "bin"))
            targets = _targets_decoder.decode(await request.read())
            data = targets_formats.encode(targets, fmt)
        except (ValueError, msgspec.DecodeError) as error:
            return web.json_response({"error": f"{error}; nothing saved"}, status=400)
        return web.Response(
            body=data,
            content_type=targets_formats.MEDIA_TYPES[fmt],
            headers={"Content-Disposition": f'attachment; filename="targets.{fmt}"'},
        )

    # ---- the WebSocket -----------------------------------------------------------------
    def _snapshot(self, statuses: list[dict[str, Any]]) -> dict[str, Any]:
        assert self._view is not None and self._desk is not None
        views = self._view.snapshot()
        self.model.note_views(views)
        mission = self.model.mission_json(self._desk.outcome(), views)
        if mission is not None:
            # The ground's proposed plan, when the page asked for one, and its adoption;
            # then every proposal heard (the ground's and the UAVs'), each checked and
            # judged from the UAVs' reported digests.
            mission["proposal"] = self._desk.proposal_json()
            mission["proposals"] = self._desk.proposals_json()
        return {
            "type": "snapshot",
            "time": time.time(),
            "uavs": [self.model.uav_json(view) for view in views],
            "mission": mission,
            "statuses": statuses,
            "alerts": self.model.alerts_json(),
            # What this server refused: requests (Host, token, origin, session), commands,
            # and bus messages by reason.
            "refused": {
                "requests": self.access.refused,
                "commands": self.commands_refused,
                "bus": bus_codec.DROPPED.counts(),
            },
        }

    async def _push(self) -> None:
        snapshot = self._snapshot(self.model.new_statuses())
        text = json.dumps(snapshot)
        for ws in list(self.sockets):
            with contextlib.suppress(ConnectionError, RuntimeError):
                await ws.send_str(text)

    async def _websocket(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=HEARTBEAT_S)
        await ws.prepare(request)
        # The whole status history first, then the live pushes.
        await ws.send_json({**self._snapshot([]), "statuses": self.model.all_statuses()})
        self.sockets.add(ws)
        try:
            # Never awaits a command: each is answered by a task of its own, so this loop
            # keeps reading the page (and the pongs that keep its socket open).
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    self._take(ws, message.data)
                elif message.type == WSMsgType.BINARY:
                    self.commands_refused += 1
                    reply = Reply(None, False, "a binary message: commands are JSON text")
                    self._answer(ws, None, _done(reply))
        finally:
            self.sockets.discard(ws)
        return ws

    def _take(self, ws: web.WebSocketResponse, data: str) -> None:
        """Acknowledge a command and have it carried out in its turn (or, sent again
        after a reconnect, answered with its first execution's reply)."""
        assert self._ledger is not None
        try:
            command = decode_command(data)
        except CommandError as error:
            self.commands_refused += 1
            log.warning("refused a command from the page: %s", error)
            self._answer(ws, None, _done(Reply(None, False, str(error))))
            return
        outcome = self._ledger.submit(command.id, lambda: self._command(command))
        self._answer(ws, command.id, outcome)

    def _answer(
        self, ws: web.WebSocketResponse, command_id: int | str | None, outcome: Awaitable[Reply]
    ) -> None:
        async def answer() -> None:
            with contextlib.suppress(ConnectionError, RuntimeError):
                # A page's command (a string id) is acknowledged as soon as it is read; a
                # script's (an integer id) gets its reply alone, as it always did.
                if isinstance(command_id, str):
                    await ws.send_json({"type": "ack", "id": command_id})
                reply = await asyncio.shield(outcome)
                if not ws.closed:
                    await ws.send_json(reply.to_json())

        task = asyncio.create_task(answer())
        self._answers.add(task)
        task.add_done_callback(self._answers.discard)

    async def _command(self, command: Command) -> Reply | Later:
        assert self._view is not None and self._desk is not None and self._coalescer
        if isinstance(command, AddTargetsCommand | RemoveTargetsCommand):
            return await self._change(command)
        try:
            reply = await asyncio.to_thread(
                execute, self.bus, self._desk, command, set(self._view.live_ids())
            )
        except Exception as error:
            log.exception("command %r failed", command)
            return Reply(command.id, False, f"failed: {error}")
        if reply.aborted and reply.mission is not None:
            self.model.aborted.add(reply.mission)
        self._coalescer.mark()
        return reply

    async def _change(self, command: ChangeCommand) -> Reply | Later:
        """A change in flight: put in its turn; its acknowledgements awaited after it
        (`Later`), so that an Abort pressed meanwhile goes out at once."""
        assert self._desk is not None and self._coalescer is not None
        try:
            put = await asyncio.to_thread(put_change_of, self.bus, self._desk, command)
        except Exception as error:
            log.exception("command %r failed", command)
            return Reply(command.id, False, f"failed: {error}")
        self._coalescer.mark()
        if isinstance(put, Reply):
            return put

        async def acknowledged() -> Reply:
            try:
                return await asyncio.to_thread(change_reply, command, put, self._stopping)
            except Exception as error:
                log.exception("command %r failed", command)
                return Reply(command.id, False, f"failed: {error}")

        return Later(acknowledged)


def _done(reply: Reply) -> asyncio.Future[Reply]:
    future: asyncio.Future[Reply] = asyncio.get_running_loop().create_future()
    future.set_result(reply)
    return future


async def serve(bus: Bus, config: GuiConfig, on_ready: Callable[[str], None]) -> None:
    """Serve the page until cancelled; `on_ready(url)` once it listens."""
    server = GuiServer(bus, config)
    runner = web.AppRunner(server.app(), access_log=None)
    await runner.setup()
    try:
        site = web.TCPSite(runner, config.host, config.port)
        await site.start()
        # The port the OS gave when asked for port 0.
        port = runner.addresses[0][1] if runner.addresses else config.port
        host = f"[{config.host}]" if ":" in config.host else config.host
        # Without the token: the caller prints this URL (docs/gui.md).
        on_ready(f"http://{host}:{port}/")
        await asyncio.Event().wait()
    finally:
        await runner.cleanup()
