"""The parameters a vehicle shows a ground station: few, real, read-only.

QGroundControl loads every parameter of a vehicle when it connects and waits for them;
a vehicle that answers none looks broken. The gateway answers with what the fleet
really flies by, the same for a station as for the fleet's own code, and nothing it
cannot vouch for:

| name | value |
|---|---|
| `FLT_PICCOLO_ID` | the UAV's Piccolo ID (its system id may differ, `--sysid`) |
| `FLT_AIRSPD_MIN`, `FLT_AIRSPD_MAX` | the airspeed envelope (m/s) the onboard plans with |
| `FLT_BANK_LIM` | the bank limit (degrees) the onboard plans its turns with |
| `FLT_ACCEPT_RAD` | the radius (m) within which a target counts as reached |

(`AircraftLimits`' defaults, as every onboard uses them, and `REACHED_RADIUS_M`.)

Every value is a REAL32 (a Piccolo ID is exact in one). They are read-only: the fleet's
aircraft are not configured from a ground station, so PARAM_SET is answered with the
unchanged value (the protocol's refusal) and a warning.
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from fleet.geo.aircraft import AircraftLimits
from fleet.mission.target_checks import REACHED_RADIUS_M

_LIMITS = AircraftLimits()
#: The longest name PARAM_VALUE carries.
NAME_CHARS = 16


@dataclass(frozen=True)
class Parameter:
    name: str
    value: float


def parameters(piccolo: int) -> tuple[Parameter, ...]:
    """UAV `piccolo`'s parameters, in index order."""
    return (
        Parameter("FLT_PICCOLO_ID", float(piccolo)),
        Parameter("FLT_AIRSPD_MIN", _LIMITS.min_airspeed),
        Parameter("FLT_AIRSPD_MAX", _LIMITS.max_airspeed),
        Parameter("FLT_BANK_LIM", _LIMITS.bank_limit_deg),
        Parameter("FLT_ACCEPT_RAD", REACHED_RADIUS_M),
    )


def _name(raw: object) -> str:
    text = raw.decode("utf-8", "replace") if isinstance(raw, bytes) else str(raw)
    return text.rstrip("\x00")[:NAME_CHARS]


def find(params: tuple[Parameter, ...], name: object, index: int) -> int | None:
    """The index PARAM_REQUEST_READ or PARAM_SET asks for: `index` if it is one (>= 0),
    else the parameter named `name`; None if there is no such parameter."""
    if 0 <= index < len(params):
        return index
    if index >= 0:
        return None
    wanted = _name(name)
    return next((i for i, p in enumerate(params) if p.name == wanted), None)


def param_value(params: tuple[Parameter, ...], index: int) -> mavlink2.MAVLink_param_value_message:
    parameter = params[index]
    return mavlink2.MAVLink_param_value_message(
        parameter.name.encode(),
        parameter.value,
        mavlink2.MAV_PARAM_TYPE_REAL32,
        len(params),
        index,
    )
