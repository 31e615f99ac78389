"""Which MAVLink commands the gateway carries out, and how (pure).

RTL aborts the UAV's part of its mission (as `ground-cli abort --uav`): as
MAV_CMD_NAV_RETURN_TO_LAUNCH, or a MAV_CMD_DO_SET_MODE or SET_MODE to the RTL custom
mode (the fleet's, ArduPlane's 11, or PX4's AUTO/RTL as MAVSDK sends it). Asking for
AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE or the older REQUEST_AUTOPILOT_CAPABILITIES),
or HOME_POSITION (MAV_CMD_GET_HOME_POSITION), is answered with it, as is
MAV_CMD_REQUEST_MESSAGE for any message in `REQUESTABLE` (BATTERY_STATUS with every
figure "not measured"). Anything else is MAV_RESULT_UNSUPPORTED: a ground station always
hears back.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, auto

from pymavlink.dialects.v20 import common as mavlink2

from ground.mavlink.vehicle import ARDUPLANE_RTL, FleetMode


class Action(Enum):
    ABORT = auto()  #: abort the UAV's part; ack once it confirmed
    SEND_MESSAGE = auto()  #: send message `message_id` once, ack accepted
    UNSUPPORTED = auto()


@dataclass(frozen=True)
class Decision:
    action: Action
    message_id: int = 0


#: The messages MAV_CMD_REQUEST_MESSAGE can ask for (the streamed ones, once more).
REQUESTABLE = frozenset(
    {
        mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
        mavlink2.MAVLINK_MSG_ID_HEARTBEAT,
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink2.MAVLINK_MSG_ID_ATTITUDE,
        mavlink2.MAVLINK_MSG_ID_VFR_HUD,
        mavlink2.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink2.MAVLINK_MSG_ID_HOME_POSITION,
        mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
        mavlink2.MAVLINK_MSG_ID_GPS_STATUS,
        mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS,
    }
)


#: PX4's RTL as MAV_CMD_DO_SET_MODE's param2 (main mode AUTO) and param3 (sub mode RTL):
#: what MAVSDK sends to a generic autopilot for Action.return_to_launch.
PX4_AUTO_MAIN_MODE = 4
PX4_RTL_SUB_MODE = 5


def is_rtl_mode(base_mode: float, custom_mode: float, sub_mode: float = 0.0) -> bool:
    """A mode change to RTL: the fleet's (ArduPlane's) RTL custom mode, or PX4's."""
    if not int(base_mode) & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return False
    if int(custom_mode) in (int(FleetMode.RTL), ARDUPLANE_RTL):
        return True
    return int(custom_mode) == PX4_AUTO_MAIN_MODE and int(sub_mode) == PX4_RTL_SUB_MODE


def decide(command: int, param1: float, param2: float, param3: float = 0.0) -> Decision:
    """What to do for COMMAND_LONG/COMMAND_INT `command` with its first three params."""
    if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return Decision(Action.ABORT)
    if command == mavlink2.MAV_CMD_DO_SET_MODE and is_rtl_mode(param1, param2, param3):
        return Decision(Action.ABORT)
    if command == mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
        return Decision(Action.SEND_MESSAGE, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    if command == mavlink2.MAV_CMD_GET_HOME_POSITION:
        return Decision(Action.SEND_MESSAGE, mavlink2.MAVLINK_MSG_ID_HOME_POSITION)
    if command == mavlink2.MAV_CMD_REQUEST_MESSAGE and int(param1) in REQUESTABLE:
        return Decision(Action.SEND_MESSAGE, int(param1))
    return Decision(Action.UNSUPPORTED)
