"""What ground stations ask of a vehicle, answered: the mission protocol and commands.

`Requests.handle` takes each decoded message from the endpoint. A message addressed to
no UAV shown is counted (`unknown_system`) and let go, as is one to the broadcast
address (uncounted: nothing there is for one vehicle to answer). One addressed to a UAV
is always answered: a mission transfer by the protocol's next step
(`mission_protocol`), a command by COMMAND_ACK (`commands`). What needs the fleet runs
on the gateway's workers and is answered when the fleet has answered: a mission's
MISSION_ACK once the fleet took it, RTL's COMMAND_ACK once the UAV reported
its part aborted (MAV_RESULT_IN_PROGRESS meanwhile, to each repeat of the command).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from concurrent.futures import Future

from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.messages import MissionTargets, Target
from fleet.mission.phase import Severity
from ground.fleet_view import UavView
from ground.mavlink import vehicle
from ground.mavlink.commands import Action, decide, is_rtl_mode
from ground.mavlink.endpoint import Address, Drop, Incoming
from ground.mavlink.fleet_link import AbortResult, TeamChoice
from ground.mavlink.gateway import Gateway, Vehicle
from ground.mavlink.mission_protocol import (
    Complete,
    MissionUpload,
    Refusal,
    Refuse,
    Request,
    Step,
    download_item,
    item_from_message,
)
from ground.mavlink.parameters import find, param_value, parameters

log = logging.getLogger(__name__)

_MISSION = mavlink2.MAV_MISSION_TYPE_MISSION
_SET_MODE_ACK = mavlink2.MAVLINK_MSG_ID_SET_MODE  # ArduPilot's COMMAND_ACK for SET_MODE


class Requests:
    def __init__(
        self, gateway: Gateway, team: TeamChoice, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.gateway = gateway
        self.team = team
        self._clock = clock
        self.uploads: dict[int, MissionUpload] = {}  #: by system id: one at a time
        self._uploaders: dict[int, Address] = {}  #: the station of each open upload
        self._to: Address | None = None  #: the station whose message is being handled
        self._sending: dict[int, Future[None]] = {}  #: a finished upload with the fleet
        self._aborting: dict[int, Future[None]] = {}

    # ---- dispatch ----------------------------------------------------------------------------
    def handle(self, incoming: Incoming) -> None:
        message = incoming.message
        self._to = incoming.peer  # answers go to the station that asked
        if message.get_type() == "TIMESYNC":
            self._timesync(message)
            return
        target = getattr(message, "target_system", None)
        if target is None:
            return  # a station's heartbeat or telemetry: nothing to answer
        found = self.gateway.vehicle(int(target))
        if found is None:
            # For all (0: nothing a vehicle must answer alone), or for a system not shown.
            if target != 0:
                self.gateway.drops.add(Drop.UNKNOWN_SYSTEM)
            return
        sysid, piccolo = found[0].sysid, found[0].piccolo
        partner = (message.get_srcSystem(), message.get_srcComponent())
        kind = message.get_type()
        if kind == "MISSION_COUNT":
            self._count(sysid, piccolo, partner, message)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self._item(sysid, piccolo, partner, message)
        elif kind == "MISSION_REQUEST_LIST":
            self._download_count(sysid, found[1].mission, partner, message)
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._download_item(sysid, found[1], partner, message)
        elif kind == "MISSION_CLEAR_ALL":
            self._ack(sysid, partner, Refusal(mavlink2.MAV_MISSION_UNSUPPORTED, "clearing is RTL"))
        elif kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._command(sysid, piccolo, partner, message)
        elif kind == "SET_MODE" and is_rtl_mode(message.base_mode, message.custom_mode):
            self._abort(sysid, piccolo, partner, _SET_MODE_ACK)
        elif kind == "SET_MODE":
            self._command_ack(sysid, partner, _SET_MODE_ACK, mavlink2.MAV_RESULT_UNSUPPORTED)
        elif kind in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            self._parameters(sysid, piccolo, kind, message)
        elif kind == "MISSION_SET_CURRENT":
            # The vehicle answers with the item it flies: the fleet chose it, not the station.
            self.gateway.say(piccolo, "the fleet chooses each UAV's target", Severity.WARNING)
            self._progress_now(found[0], found[1])
        else:
            log.debug("system %d: %s not answered (not mapped)", sysid, kind)

    def tick(self) -> None:
        """Ask a silent station again for its item, or give its upload up."""
        now = self._clock()
        for sysid, upload in list(self.uploads.items()):
            step = upload.on_tick(now)
            if step is not None:
                self._to = self._uploaders.get(sysid)
                self._step(sysid, 0, upload.partner, step)

    def _progress_now(self, found: Vehicle, view: UavView) -> None:
        targets = self.gateway.mission_of(view.mission)
        if targets is not None and view.target is not None:
            current = vehicle.mission_current(view.target, len(targets.targets), False)
            self._reply(found.sysid, current)

    # ---- parameters and time ---------------------------------------------------------------
    def _parameters(self, sysid: int, piccolo: int, kind: str, message: object) -> None:
        params = parameters(piccolo)
        if kind == "PARAM_REQUEST_LIST":
            for index in range(len(params)):
                self._reply(sysid, param_value(params, index))
            return
        name = getattr(message, "param_id", b"")
        found = find(params, name, int(getattr(message, "param_index", -1)))
        if found is None:
            # The protocol's answer to an unknown name: none (the station times out).
            log.info("system %d: no parameter %r", sysid, name)
            return
        index = found
        if kind == "PARAM_SET":
            # Refused the protocol's way: the value it still has.
            self.gateway.say(
                piccolo, f"{params[index].name} is read-only: not changed", Severity.WARNING
            )
        self._reply(sysid, param_value(params, index))

    def _timesync(self, message: object) -> None:
        """A station's TIMESYNC request (tc1 = 0) answered from every vehicle shown: tc1
        our time (ns), ts1 theirs."""
        if int(getattr(message, "tc1")) != 0:  # noqa: B009
            return  # an answer to a request of ours: the gateway sends none
        now_ns = time.monotonic_ns()
        for found, _ in self.gateway.live_vehicles():
            ts1 = int(getattr(message, "ts1"))  # noqa: B009
            self._reply(found.sysid, mavlink2.MAVLink_timesync_message(now_ns, ts1))

    # ---- mission upload ----------------------------------------------------------------------
    def _count(self, sysid: int, piccolo: int, partner: tuple[int, int], message: object) -> None:
        count = int(getattr(message, "count"))  # noqa: B009
        mission_type = int(getattr(message, "mission_type", _MISSION))
        pending = self._sending.get(sysid)
        if pending is not None and not pending.done():
            refusal = Refusal(mavlink2.MAV_MISSION_DENIED, "the last mission is still being sent")
            self._ack(sysid, partner, refusal, mission_type)
            return
        open_upload = self.uploads.get(sysid)
        if open_upload is not None and (open_upload.partner, self._uploaders.get(sysid)) != (
            partner,
            self._to,
        ):
            # One upload at a time: another station's count neither restarts nor joins it.
            self.gateway.drops.add(Drop.BUSY)
            refusal = Refusal(
                mavlink2.MAV_MISSION_DENIED,
                f"another station is uploading a mission to UAV {piccolo}; try again",
            )
            self._ack(sysid, partner, refusal, mission_type)
            return
        upload, step = MissionUpload.start(partner, count, mission_type, self._clock())
        if upload is None:
            self.gateway.drops.add(Drop.REFUSED)
            self._close_upload(sysid)
        else:
            # A new MISSION_COUNT from its station restarts the transfer (the protocol's rule).
            self.uploads[sysid] = upload
            if self._to is not None:
                self._uploaders[sysid] = self._to
        self._step(sysid, piccolo, partner, step, mission_type)

    def _close_upload(self, sysid: int) -> None:
        self.uploads.pop(sysid, None)
        self._uploaders.pop(sysid, None)

    def _item(self, sysid: int, piccolo: int, partner: tuple[int, int], message: object) -> None:
        upload = self.uploads.get(sysid)
        if upload is None:
            return  # a late repeat of an item of a transfer that is over
        if upload.partner != partner or self._uploaders.get(sysid) != self._to:
            self.gateway.drops.add(Drop.BUSY)  # another station's item: never mixed in
            return
        step = upload.on_item(item_from_message(message), self._clock())
        if step is not None:
            self._step(sysid, piccolo, partner, step)

    def _step(
        self,
        sysid: int,
        piccolo: int,
        partner: tuple[int, int],
        step: Step,
        mission_type: int = _MISSION,
    ) -> None:
        if isinstance(step, Request):
            self._reply(
                sysid,
                mavlink2.MAVLink_mission_request_int_message(
                    partner[0], partner[1], step.seq, mission_type
                ),
            )
        elif isinstance(step, Refuse):
            self._close_upload(sysid)
            self._ack(sysid, partner, step.refusal, mission_type)
        elif isinstance(step, Complete):
            self._close_upload(sysid)
            self._sending[sysid] = self.gateway.workers.submit(
                self._send_mission, sysid, piccolo, partner, step.targets, self._to
            )

    def _send_mission(
        self,
        sysid: int,
        piccolo: int,
        partner: tuple[int, int],
        targets: tuple[Target, ...],
        to: Address | None,
    ) -> None:
        """(A worker.) Hand the mission to the fleet; MISSION_ACK says if it took it."""
        live = self.gateway.view.live_ids()
        outcome = self.gateway.fleet.send_mission(piccolo, targets, self.team, live)
        if outcome.mission is None:
            # Refused by the checks (nothing sent), or sent and not acknowledged.
            result = (
                mavlink2.MAV_MISSION_DENIED if outcome.sent is None else mavlink2.MAV_MISSION_ERROR
            )
            what = "not sent" if outcome.sent is None else "sent"
            self._post_ack(sysid, partner, Refusal(result, f"{what}: {outcome.problem}"), to)
            return
        self.gateway.remember_mission(MissionTargets(outcome.mission, outcome.team, targets))
        team = ", ".join(map(str, outcome.team))
        accepted = mavlink2.MAVLink_mission_ack_message(*partner, mavlink2.MAV_MISSION_ACCEPTED)
        self.gateway.outbox.put((sysid, accepted, to))
        self._post_text(piccolo, f"mission {outcome.mission}: {len(targets)} targets to {team}")

    def _ack(
        self, sysid: int, partner: tuple[int, int], refusal: Refusal, mission_type: int = _MISSION
    ) -> None:
        log.warning("system %d: mission refused: %s", sysid, refusal.reason)
        self.gateway.say(self._piccolo(sysid), refusal.reason, Severity.ERROR)
        self._reply(
            sysid, mavlink2.MAVLink_mission_ack_message(*partner, refusal.result, mission_type)
        )

    def _reply(self, sysid: int, message: mavlink2.MAVLink_message) -> None:
        """An answer, to the station that asked only."""
        self.gateway.send(sysid, message, self._to)

    def _post_ack(
        self, sysid: int, partner: tuple[int, int], refusal: Refusal, to: Address | None
    ) -> None:
        log.warning("system %d: mission refused: %s", sysid, refusal.reason)
        self._post_text(self._piccolo(sysid), refusal.reason, Severity.ERROR)
        self.gateway.outbox.put(
            (sysid, mavlink2.MAVLink_mission_ack_message(*partner, refusal.result), to)
        )

    def _post_text(self, piccolo: int, text: str, severity: Severity = Severity.INFO) -> None:
        sysid = self.gateway.sysids.sysid_of(piccolo)
        if sysid is not None:
            for message in self.gateway.status_texts(text, severity):
                self.gateway.outbox.put((sysid, message, None))

    def _piccolo(self, sysid: int) -> int:
        found = self.gateway.vehicles.get(sysid)
        return found.piccolo if found is not None else 0

    # ---- mission download --------------------------------------------------------------------
    def _download_count(
        self, sysid: int, mission: int | None, partner: tuple[int, int], message: object
    ) -> None:
        mission_type = int(getattr(message, "mission_type", _MISSION))
        targets = self.gateway.mission_of(mission)
        count = len(targets.targets) if targets is not None and mission_type == _MISSION else 0
        self._reply(sysid, mavlink2.MAVLink_mission_count_message(*partner, count, mission_type))

    def _download_item(
        self, sysid: int, view: UavView, partner: tuple[int, int], message: object
    ) -> None:
        targets = self.gateway.mission_of(view.mission)
        seq = int(getattr(message, "seq"))  # noqa: B009
        item = (
            download_item(targets.targets, seq, view.target, partner)
            if targets is not None
            else None
        )
        if item is None:
            refusal = Refusal(mavlink2.MAV_MISSION_INVALID_SEQUENCE, f"no mission item {seq}")
            self._ack(sysid, partner, refusal)
            return
        self._reply(sysid, item)

    # ---- commands ----------------------------------------------------------------------------
    def _command(self, sysid: int, piccolo: int, partner: tuple[int, int], message: object) -> None:
        command = int(getattr(message, "command"))  # noqa: B009
        decision = decide(
            command,
            float(getattr(message, "param1")),  # noqa: B009
            float(getattr(message, "param2")),  # noqa: B009
            float(getattr(message, "param3")),  # noqa: B009
        )
        if decision.action is Action.ABORT:
            self._abort(sysid, piccolo, partner, command)
            return
        if decision.action is Action.SEND_MESSAGE:
            built = self._requested(sysid, piccolo, decision.message_id)
            if built is None:
                # What it needs is not known yet (no telemetry, no home): ask again later.
                result = mavlink2.MAV_RESULT_TEMPORARILY_REJECTED
                self._command_ack(sysid, partner, command, result)
                return
            self._command_ack(sysid, partner, command, mavlink2.MAV_RESULT_ACCEPTED)
            self._reply(sysid, built)
            return
        log.info(
            "system %d: command %d unsupported (param1 %g)",
            sysid,
            command,
            float(getattr(message, "param1")),  # noqa: B009
        )
        self._command_ack(sysid, partner, command, mavlink2.MAV_RESULT_UNSUPPORTED)

    def _requested(
        self, sysid: int, piccolo: int, message_id: int
    ) -> mavlink2.MAVLink_message | None:
        """The message asked for, as the UAV is now; None while what it says is unknown."""
        if message_id == mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return vehicle.autopilot_version(piccolo)
        if message_id == mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS:
            return vehicle.battery_status()
        found = self.gateway.vehicle(sysid)
        if found is None:
            return None
        view, telemetry = found[1], self.gateway.view.telemetry(piccolo)
        boot = self.gateway.boot_ms()
        home = self.gateway.home_of(piccolo)
        if message_id == mavlink2.MAVLINK_MSG_ID_HEARTBEAT:
            return vehicle.heartbeat(view, telemetry)
        if message_id == mavlink2.MAVLINK_MSG_ID_SYS_STATUS:
            return vehicle.sys_status(view, telemetry, self.gateway.drops.total())
        if message_id == mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            return vehicle.extended_sys_state(telemetry)
        if message_id == mavlink2.MAVLINK_MSG_ID_HOME_POSITION:
            return vehicle.home_position(*home) if home is not None else None
        if telemetry is None:
            return None
        built: mavlink2.MAVLink_message | None = None
        if message_id == mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT:
            built = vehicle.gps_raw(telemetry, boot)
        elif message_id == mavlink2.MAVLINK_MSG_ID_GPS_STATUS:
            built = vehicle.gps_status(telemetry)
        elif message_id == mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            built = vehicle.global_position(telemetry, boot)
        elif message_id == mavlink2.MAVLINK_MSG_ID_ATTITUDE:
            built = vehicle.attitude(telemetry, boot)
        elif message_id == mavlink2.MAVLINK_MSG_ID_VFR_HUD:
            built = vehicle.vfr_hud(view, telemetry)
        return built

    def _command_ack(self, sysid: int, partner: tuple[int, int], command: int, result: int) -> None:
        self._reply(sysid, _command_ack(partner, command, result))

    def _abort(self, sysid: int, piccolo: int, partner: tuple[int, int], command: int) -> None:
        pending = self._aborting.get(sysid)
        if pending is not None and not pending.done():
            self._command_ack(sysid, partner, command, mavlink2.MAV_RESULT_IN_PROGRESS)
            return
        self._command_ack(sysid, partner, command, mavlink2.MAV_RESULT_IN_PROGRESS)
        self._aborting[sysid] = self.gateway.workers.submit(
            self._abort_and_confirm, sysid, piccolo, partner, command, self._to
        )

    def _abort_and_confirm(
        self, sysid: int, piccolo: int, partner: tuple[int, int], command: int, to: Address | None
    ) -> None:
        """(A worker.) The final COMMAND_ACK only once the UAV said it aborted."""
        result, text = self.gateway.fleet.abort(piccolo)
        mav_result = {
            AbortResult.CONFIRMED: mavlink2.MAV_RESULT_ACCEPTED,
            AbortResult.NOT_ON_A_MISSION: mavlink2.MAV_RESULT_DENIED,
            AbortResult.NOT_CONFIRMED: mavlink2.MAV_RESULT_FAILED,
        }[result]
        log.info("system %d: RTL: %s", sysid, text)
        severity = Severity.INFO if result is AbortResult.CONFIRMED else Severity.WARNING
        self._post_text(piccolo, f"RTL: {text}", severity)
        self.gateway.outbox.put((sysid, _command_ack(partner, command, mav_result), to))


def _command_ack(
    partner: tuple[int, int], command: int, result: int
) -> mavlink2.MAVLink_command_ack_message:
    return mavlink2.MAVLink_command_ack_message(command, result, 0, 0, partner[0], partner[1])
