"""A mission's outcome as the lines `send-targets --wait` and `mission` print."""

from __future__ import annotations

from ground.mission_outcome import MissionOutcome


def summary_lines(outcome: MissionOutcome) -> list[str]:
    agreement = outcome.agreement
    lines = [
        f"mission {outcome.mission}: team {', '.join(map(str, outcome.team))}; "
        f"{len(outcome.targets)} targets"
    ]
    for uav in outcome.team:
        result = outcome.results.get(uav)
        report = outcome.assignments.get(uav)
        times = (
            "no result"
            if result is None
            else "times " + ", ".join("-" if t is None else f"{t:.1f}" for t in result.times) + " s"
        )
        if report is None:
            choice = "not committed"
        elif report.target is None:
            choice = "no target"
        else:
            eta = "" if report.eta_s is None else f" ETA {report.eta_s:.0f} s"
            choice = f"target {report.target}{eta}"
            queue = report.queues.get(uav, ())
            if len(queue) > 1:  # the rest of its queue, in order
                choice += f", then {', '.join(map(str, queue[1:]))}"
        if uav in outcome.lost:
            choice = "LOST (liveliness gone) " + choice
        elif uav in outcome.declined:
            choice = "declined " + choice
        phase = outcome.phases.get(uav)
        reason = outcome.reasons.get(uav)
        state = f"; phase {phase}" + (f" ({reason})" if reason else "") if phase else ""
        lines.append(f"  UAV {uav}: {choice}; {times}{state}")
    if outcome.epoch:
        revision = f" (mission revision {outcome.revision})" if outcome.revision else ""
        lines.append(f"  re-planned: epoch {outcome.epoch}{revision}")
    for row in outcome.membership():
        now = "out" if row["out"] else "back in"
        lines.append(
            f"  UAV {row['uav']}: left {row['left']}x ({row['why']}), came back "
            f"{row['back']}x: {now}"
        )
    asked = outcome.asked()
    if asked:
        who = ", ".join(f"UAV {uav} {count}x" for uav, count in asked.items())
        lines.append(f"  re-planned in the air of now: asked by {who}")
    for index, uavs in outcome.flown_twice().items():
        lines.append(f"  target {index}: FLOWN TWICE, by UAVs {', '.join(map(str, uavs))}")
    for target in outcome.target_states():
        if target["state"] == "unserved":
            lines.append(f"  target {target['index']}: unserved: {target['reason']}")
        elif target["state"] == "reached":
            lines.append(f"  target {target['index']}: reached by UAV {target['uav']}")
        elif target["state"] == "removed":
            lines.append(f"  target {target['index']}: removed in flight")
        elif target["state"] != "assigned":
            lines.append(
                f"  target {target['index']}: {target['state']} (UAV {target['uav']}): "
                f"{target['reason']}"
            )
    unassigned = outcome.unassigned()
    lines.append(f"  unassigned targets: {', '.join(map(str, unassigned)) or 'none'}")
    if outcome.superseded_by is not None:
        lines.append(
            f"  SUPERSEDED by mission {outcome.superseded_by}: the team no longer flies "
            f"mission {outcome.mission}"
        )
    if agreement.agreed:
        digest = agreement.reference.digest[:12] if agreement.reference else ""
        lines.append(f"  agreed: yes (digest {digest})")
    else:
        why = []
        if agreement.disagreed:
            why.append("disagreed: " + ", ".join(map(str, agreement.disagreed)))
        if agreement.missing:
            why.append("not committed: " + ", ".join(map(str, agreement.missing)))
        lines.append(f"  agreed: no ({'; '.join(why)})")
    return lines


def unreached_lines(outcome: MissionOutcome) -> list[str]:
    """One line per target not reached: who holds it and where it stands, or why nobody
    does (what `mission --until-reached` says when it gives up)."""
    lines = []
    for target in outcome.target_states():
        state = target["state"]
        if state in ("reached", "removed"):
            continue
        index, uav = target["index"], target["uav"]
        if state == "assigned":
            phase = outcome.phases.get(uav)
            place, eta = target.get("place"), target.get("eta_s")
            queued = f" (place {place} in its queue" if place is not None else ""
            if queued:
                queued += f", predicted {eta:.0f} s after the plan)" if eta is not None else ")"
            where = f"; phase {phase}" if phase else ""
            if uav in outcome.lost:
                where += "; LOST (liveliness gone)"
            lines.append(f"  target {index}: not reached: UAV {uav} holds it{queued}{where}")
        elif state == "unserved":
            lines.append(f"  target {index}: unserved: {target['reason']}")
        else:
            lines.append(f"  target {index}: {state} (UAV {uav}): {target['reason']}")
    return lines
