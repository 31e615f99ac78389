"""The page's Load and Save of no-fly zones (GeoJSON), through `fleet.files.zones_file`.

* `POST /api/zones/import?name=FILE` (the file's bytes): `{"zones": [{"ring": [[lat,
  lon], ...], "name": ...}, ...]}`, or 400 with `{"error": ...}` naming the file, the
  feature and what was wrong (the same checks as `send-targets --no-fly`);
* `POST /api/zones/export` (a JSON list of such zones): the GeoJSON file, or 400.
"""

from __future__ import annotations

import msgspec
from aiohttp import web

from fleet.files.zones_file import ZonesFileError, decode_zones, encode_zones
from fleet.mission.messages import NoFlyZone
from fleet.mission.no_fly import mission_zone_problem

__all__ = ["add_routes"]

_zones_decoder = msgspec.json.Decoder(list[NoFlyZone])


async def import_zones(request: web.Request) -> web.Response:
    name = request.query.get("name", "zones.geojson")
    try:
        zones = decode_zones(await request.read(), name)
    except ZonesFileError as error:
        return web.json_response({"error": f"{error}; nothing loaded"}, status=400)
    return web.json_response({"zones": [msgspec.to_builtins(zone) for zone in zones]})


async def export_zones(request: web.Request) -> web.Response:
    try:
        zones = _zones_decoder.decode(await request.read())
    except (ValueError, msgspec.DecodeError) as error:
        return web.json_response({"error": f"{error}; nothing saved"}, status=400)
    problem = mission_zone_problem(zones)
    if problem is not None:
        return web.json_response({"error": f"{problem}; nothing saved"}, status=400)
    return web.Response(
        body=encode_zones(zones),
        content_type="application/geo+json",
        headers={"Content-Disposition": 'attachment; filename="zones.geojson"'},
    )


def add_routes(app: web.Application) -> None:
    app.router.add_post("/api/zones/import", import_zones)
    app.router.add_post("/api/zones/export", export_zones)
