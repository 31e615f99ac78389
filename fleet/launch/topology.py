"""How the fleet's Zenoh routers are laid out, and who connects to whom.

* `star`: one router (the ground's); every onboard and the ground are its clients. The
  router is a single point of failure.
* `router-per-uav`: the ground's router, plus one router per UAV. UAV i's router connects
  to the ground's router and to the next UAV's router on a ring (so each router has the
  ground and two ring neighbours: 3 links, 2N in all, never a full mesh: at 50 UAVs 100
  links rather than 1,275). UAV i's onboard is a client of its own router, falling back
  to its ring neighbour's, then to the ground's. With the ground's router gone, the ring
  still joins every UAV; with one UAV's router gone, the ring becomes a line, still whole.
"""

from __future__ import annotations

from enum import StrEnum


class Topology(StrEnum):
    STAR = "star"
    ROUTER_PER_UAV = "router-per-uav"


def ring_links(uav_ids: list[int]) -> dict[int, list[int]]:
    """UAV id -> the UAV routers its router connects to: the next one on the ring.

    Each link is opened from one side only (both sides would make two links).
    """
    ids = sorted(uav_ids)
    if len(ids) < 2:
        return {uav: [] for uav in ids}
    if len(ids) == 2:
        return {ids[0]: [ids[1]], ids[1]: []}
    return {uav: [ids[(i + 1) % len(ids)]] for i, uav in enumerate(ids)}


def fallbacks(uav_ids: list[int], uav: int) -> list[int]:
    """The UAV routers UAV `uav`'s onboard tries, in order: its own, then its neighbours'."""
    ids = sorted(uav_ids)
    i = ids.index(uav)
    order = [uav, ids[(i + 1) % len(ids)], ids[(i - 1) % len(ids)]]
    return list(dict.fromkeys(order))
