"""Taking part in a mission: its targets, the team's exchange, re-plans, an abort.

A mission's targets start a round (fleet.consensus.mission_round): this UAV computes
its approach times and publishes them (onboard.own_result), hears its teammates', and
decides (onboard.mission_decision) or adopts a teammate's decision; it then flies the
target it is assigned (onboard.target_flight). A target that cannot be flown is `failed` and
released, and the UAVs still in the mission re-plan it; so is one of a teammate that
dropped out or whose liveliness stayed gone. A re-plan is solved again from every
survivor's standing, its approach times from where it is now (fleet.consensus.resolve):
this UAV gives its own and waits for its teammates' (the append plan of
fleet.consensus.replan when one is overdue). The same re-plan is asked for by a UAV whose
air (smoothed wind, airspeed) moved away from the air its plan timed its legs in
(onboard.air_watch): an epoch of its own, which its teammates take from its standing.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Protocol

import msgspec

from fleet.consensus.heal import Rank
from fleet.consensus.legs import AIRSPEED_RANGE, Air, leg_from_here
from fleet.consensus.mission_change import first_revision
from fleet.consensus.mission_round import (
    MissionRound,
    Settled,
    assignment_problem,
    predicted_arrival,
    targets_problem,
)
from fleet.consensus.proposal import ProposalRefused
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.wind import Wind
from fleet.mission import claims
from fleet.mission.key_space import KeySpace
from fleet.mission.lifecycle import Observation, advance
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    PlanProposal,
    StatusText,
    TargetOutcome,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.mission.recent_ids import RecentIds
from fleet.mission.status_kind import StatusKind
from fleet.transport.bus_codec import DROPPED, DropReason
from fleet.transport.refusal_log import RefusalLog
from onboard.air_watch import BEFORE_LEG_S, AirWatch, FlyingAir
from onboard.approach_plan import ApproachPlan
from onboard.catch_up import CatchUp
from onboard.early_proposals import EarlyProposals
from onboard.link_watch import LINK_LOST_S, LinkWatch
from onboard.mission_decision import MissionDecision
from onboard.mission_phase import MissionPhase
from onboard.own_result import OwnResult
from onboard.plan_proposer import PlanProposer
from onboard.state_report import Say
from onboard.target_flight import FlightNews, TargetFlight
from onboard.team_presence import TeamPresence

log = logging.getLogger(__name__)
#: Proposals refused as they arrive: a hostile teammate may send them as fast as it likes.
_refusals = RefusalLog(log)

#: Results for missions not seen yet are kept, at most this many, for when they start.
MAX_EARLY_RESULTS = 256
#: The airspeeds a result carries are clamped to these (onboard.own_result.flown_air).
_LIMITS = AircraftLimits()


class MissionOutputs(Protocol):
    def publish(self, key: str, message: msgspec.Struct) -> None: ...
    def send_ground(self, message: StatusText | UavResult) -> None: ...
    def fetch_results(self, mission: int, uavs: tuple[int, ...]) -> None: ...
    def fetch_assignments(self, mission: int) -> None: ...
    def fetch_missions(self) -> None: ...
    def fetch_outcomes(self, mission: int, uavs: tuple[int, ...]) -> None: ...
    def fetch_standings(self, mission: int, uavs: tuple[int, ...], basis: str | None) -> None: ...


@dataclass
class MissionParticipation:
    uav_id: int
    key_space: KeySpace
    outputs: MissionOutputs
    plan: ApproachPlan
    team: TeamPresence
    life: MissionPhase
    link: LinkWatch
    flight: TargetFlight
    say: Say
    #: Re-plans solved again from the survivors' standings (MissionRound.resolving).
    fresh_replans: bool = True
    #: This UAV's own proposer (`--propose`); None: it proposes nothing.
    proposer: PlanProposer | None = None
    round: MissionRound | None = None
    #: A snapshot of what this UAV settled of its mission (`Settled`), replaced as it
    #: changes: the bus threads drop the assignment reports it covers by their header.
    settled: Settled | None = None
    catch_up: CatchUp = field(init=False)
    decision: MissionDecision = field(init=False)
    own: OwnResult = field(init=False)
    _early_results: list[UavResult] = field(default_factory=list)
    #: Proposals for missions not held yet, checked when the mission arrives (bounded).
    _early_proposals: EarlyProposals = field(default_factory=EarlyProposals)
    #: The missions aborted, the newest only: a stream of aborts cannot grow it forever.
    _aborted: RecentIds = field(default_factory=RecentIds)
    _abort: MissionAbort | None = None  #: the abort this UAV obeyed last (relayed by query)
    #: A target committed before the first telemetry since the start: written once heard.
    _write_awaited: bool = False
    #: (mission, target, seconds): its time for the leg it flies, timed when it began it
    #: (`leg_s`); None before any.
    _leg: tuple[int, int, float | None] | None = None
    #: Following its teammates' epochs (no epoch 0 of its own: a restart, a late join),
    #: the append plan their standings are for, which this UAV stands for too once it can
    #: (`_stand_with_teammates`); None when there is none to give.
    _teammates_basis: str | None = None
    #: Whether the air moved away from the air the plan in force times this UAV's legs
    #: in (onboard.air_watch): it then asks its team for a re-plan in the air of now.
    air: AirWatch = field(default_factory=AirWatch)
    #: Re-based onto a plan built without it (fleet.consensus.heal), and not counted in
    #: yet: it stands for each plan it follows until one counts it in (`_ask_to_join`).
    _joining: bool = False

    def __post_init__(self) -> None:
        self.catch_up = CatchUp(self.outputs, lambda: self.round.mission if self.round else None)
        self.decision = MissionDecision(self.uav_id, self.outputs, self.team, self.say)
        self.own = OwnResult(
            self.uav_id,
            self.key_space,
            self.outputs,
            self.plan,
            self.life,
            self.say,
            will_propose=self.proposer.will_propose if self.proposer is not None else None,
        )

    # ---- what the flight tells its mission ---------------------------------------------------
    def on_flight(self, news: FlightNews | None, now: float) -> None:
        """Act on what a flight event handler answered (onboard.target_flight)."""
        if news is FlightNews.REACHED:
            self.publish_outcome(Phase.REACHED, None, self.flight.target)
            self.fly_next(now)
            self._replan_if_finished(now)
        elif news is FlightNews.STALE_TARGET:
            self._leave_stale_target(now)

    def _leave_stale_target(self, now: float) -> None:
        if self.decided():  # before, it may still be handed that very target
            self.flight.leave_stale_target(now)

    def decided(self) -> bool:
        return self.round is not None and self.round.committed is not None

    def current(self) -> int | None:
        return self.round.mission if self.round else None

    def publish_outcome(self, phase: Phase, reason: str | None, target: int | None) -> None:
        if self.round is None:
            return
        if phase == Phase.REACHED:
            self.round.target_reached(self.uav_id, target)
        known = dict(sorted(self.round.reached_targets.items()))
        outcome = TargetOutcome(self.round.mission, self.uav_id, target, phase, reason, known)
        self.round.outcome = outcome
        self.outputs.publish(self.key_space.mission_outcome(outcome.mission, self.uav_id), outcome)

    # ---- a mission's targets -----------------------------------------------------------------
    def on_targets(self, targets: MissionTargets, now: float, *, replayed: bool = False) -> None:
        """A mission's targets, heard live or (`replayed`) in reply to a catch-up."""
        if self.uav_id not in targets.team:
            return
        current = self.round.mission if self.round else None
        if current is not None and targets.mission <= current:
            if targets.mission == current and targets.revision > 0:
                self._on_change(targets, now)
            return  # a repeat of the current mission, or a stale one
        if targets.mission in self._aborted:
            # Its abort came first (this UAV was away when the mission was sent): the
            # mission still replaces the old one, as on every teammate, and shows aborted.
            self._start_round(targets, now)
            self.life.observe(Observation.ABORTED)
            text = f"mission {targets.mission} arrived already aborted: not flying it"
            self.say(StatusKind.ARRIVED_ABORTED, text, now, mission=targets.mission)
            return
        problem = targets_problem(targets)
        if problem is not None:
            # Bad input never disturbs the mission in progress; it is counted as refused.
            DROPPED.add(DropReason.INVALID)
            text = f"error: mission {targets.mission} refused: {problem}"
            self.say(StatusKind.MISSION_REFUSED, text, now, mission=targets.mission)
            return
        # Heard just after this module was suspended, a mission may have been sent
        # while it was: its teammates may have decided on it already.
        late = replayed or self.catch_up.resumed(now)
        mission_round = self._start_round(first_revision(targets), now, late=late)
        if targets.revision > 0:
            mission_round.amend(targets)  # changed in flight already: taken once committed
        if late:
            # Learnt from a catch-up (a late join, a restart) or after a freeze: the
            # team may have decided on it already, and this UAV adopts that. A mission
            # heard live is as new to the team as to this UAV: asking would cost every
            # teammate three queries while they all plan.
            self.outputs.fetch_assignments(targets.mission)
        if self.link.gps is None:
            self._decline(f"mission {targets.mission}: no GPS telemetry yet", now)
        elif self.link.lost(now):
            self._decline(f"mission {targets.mission}: autopilot link lost", now)
        elif not self.flight.enabled:
            text = f"mission {targets.mission}: module off, not taking part"
            self.say(StatusKind.SITTING_OUT, text, now, mission=targets.mission)
            self.own.publish_none(mission_round, now)
        else:
            self._start_planning(now)
        mission_round.prepare()  # the legs, while the planner runs: not in the decision

    def _decline(self, why: str, now: float) -> None:
        """Take no part in the current mission: an all-None result says so to the team."""
        assert self.round is not None
        text = f"warning: {why}: not taking part"
        self.say(StatusKind.NOT_TAKING_PART, text, now, mission=self.round.mission)
        self.own.publish_none(self.round, now)
        self.life.reason = why

    def _start_round(
        self, targets: MissionTargets, now: float, *, late: bool = False
    ) -> MissionRound:
        """Replace the mission in one step: nothing of the old one survives it."""
        # Cancel first: the resume submitted next must survive the new mission's start.
        self.flight.restart(f"mission {targets.mission} started", now)
        self.round = MissionRound(
            targets, self.uav_id, now, late=late, resolving=self.fresh_replans
        )
        self.own.standing = None
        self.own.stood.clear()
        self._teammates_basis = None
        self.air.follow(None, self._aircraft_clock())
        self._joining = False
        self.flight.zones = targets.zones
        self.life.observe(Observation.MISSION_STARTED)
        self.own.plan.forget()
        self.flight.hold(None, None)
        early, self._early_results = self._early_results, []
        for result in early:
            if result.mission == targets.mission:
                self.round.add_result(result)
            elif result.mission > targets.mission:
                self._early_results.append(result)
        proposals, stale = self._early_proposals.take(targets.mission)
        self._no_mission(stale, f"mission {targets.mission} superseded it")
        for proposal in proposals:
            self.on_proposal(proposal, now)  # checked as if heard now
        self._settle()
        return self.round

    def _settle(self) -> None:
        """Publish a new snapshot of what this UAV settled (after any change to it)."""
        mission_round = self.round
        if mission_round is not None:
            self.settled = mission_round.settled(mission_round.mission in self._aborted)

    # ---- the plan ------------------------------------------------------------------------------
    def _start_planning(self, now: float) -> None:
        gps = self.link.gps
        assert self.round is not None and gps is not None
        # Averaged like the wind: the result carries it, and every leg of the plan is
        # timed at it (on JSBSim one reading is off its mean by a gust's 0.9 m/s).
        speed = self.link.smoothed_airspeed()
        if not self.own.start(self.round, gps, now, self.link.wind.value, speed):
            self._decline(f"mission {self.round.mission}: the planner refused the request", now)

    def collect_plan(self, now: float) -> None:
        if self.own.collect(self.round, now):
            self._resolve_ready(now)  # this UAV's own standing may be the last one

    # ---- the team's exchange -------------------------------------------------------------------
    def on_result(self, result: UavResult, now: float) -> None:
        if result.basis is not None:
            self._on_standing(result, now)
            return
        mission_round = self.round
        if mission_round is None or result.mission > mission_round.mission:
            self._early_results = [*self._early_results, result][-MAX_EARLY_RESULTS:]
            # A teammate works on a mission this UAV has not heard: its put may not
            # reach this UAV at all (in a secure router mesh without the ground's router,
            # a UAV's router relays only what its own UAV may write), but a catch-up's
            # query does: ask for the live missions (at most every CATCH_UP_INTERVAL_S).
            self.catch_up.request(now)
            return
        if result.uav == self.uav_id or not mission_round.add_result(result):
            return
        mission_round.heard(now)
        if mission_round.committed is not None and mission_round.released:
            self._replan(now)  # it may have waited for this result

    def _on_standing(self, standing: UavResult, now: float) -> None:
        """A teammate's standing for a re-plan (fleet.consensus.resolve): kept, and the
        re-plan solved again once every survivor's is in."""
        mission_round = self.round
        if mission_round is None or standing.uav == self.uav_id:
            return
        self._count_in(standing, now)
        if mission_round.add_standing(standing):
            self._resolve_ready(now)
            if mission_round.take_asked(standing.uav, standing.asked):
                # It asked for a re-plan in the air of now: the same epoch here.
                self.say(
                    StatusKind.REPLANNED,
                    f"mission {mission_round.mission}: UAV {standing.uav} asks for a "
                    "re-plan in the air of now; re-planning",
                    now,
                    mission=mission_round.mission,
                )
                self._replan(now)
                self._settle()
            if mission_round.base is None and mission_round.committed is not None:
                assert standing.basis is not None
                self._teammates_basis = standing.basis
                self._stand_with_teammates(now)

    def _count_in(self, standing: UavResult, now: float) -> None:
        """A standing from a team UAV the plan followed was built without: a UAV that
        re-based onto it after a heal (fleet.consensus.heal) says where it stands, alive
        and with telemetry. It is counted in as a rejoining UAV is (`_rejoin`): the next
        epoch solves what is left with it taking part. A standing with no time (a UAV
        that takes no more targets) counts nobody in."""
        mission_round = self.round
        if mission_round is None or mission_round.committed is None:
            return
        if not mission_round.resolving or standing.mission != mission_round.mission:
            return
        uav = standing.uav
        if not mission_round.joinable(uav) or uav not in self.team.alive:
            return
        if not any(t is not None for t in standing.times):
            return
        self._count_back(uav, now, f"UAV {uav} re-based onto this plan; re-planning with it")

    def _stand_with_teammates(self, now: float) -> None:
        """Following its teammates' epochs, this UAV cannot compute the append plan they
        wait on (it lacks epoch 0), but their standings name it: it gives its own for it,
        so that they solve the re-plan with it (a UAV back from a restart) without
        waiting STANDINGS_WAIT_S for the append plan, which it would then follow and only
        then stand for. A standing for a plan that does not count it in is ignored, unless
        the plan was built without it: then it counts it in (`_count_in`)."""
        basis = self._teammates_basis
        mission_round = self.round
        if basis is None or mission_round is None or basis in self.own.stood:
            return
        if mission_round.base is not None or self._dropped(self.uav_id):
            self._teammates_basis = None
            return
        if self._stand(now, basis):
            self._teammates_basis = None

    def _replannable(self) -> MissionRound | None:
        """The round, if it may still be re-planned: neither its mission nor this UAV
        aborted."""
        mission_round = self.round
        if mission_round is None or mission_round.mission in self._aborted:
            return None
        return None if self.life.phase == Phase.ABORTED else mission_round

    def _resolve_ready(self, now: float) -> None:
        mission_round = self._replannable()
        if mission_round is None:
            return
        report = mission_round.resolve_ready()
        if report is not None:
            self.say(
                StatusKind.REPLANNED,
                f"mission {report.mission}: re-plan epoch {report.epoch} solved again from "
                f"{len(MissionRound.survivors(report))} survivors' fresh times",
                now,
                mission=report.mission,
            )
            self._apply(report, now)

    def _stand(self, now: float, teammates_basis: str | None = None) -> bool:
        """Give this UAV's standing for the re-plan awaited or followed (or, following
        its teammates' epochs, for the append plan `teammates_basis` their standings
        name), once: its approach times from where it is now. A UAV that takes no more
        targets (the module off, its part preempted or aborted) gives one with no time;
        one that cannot plan now (no GPS, its autopilot link lost, the planner refused)
        gives none, and the team commits the append plan when the wait is over. False
        when it could not plan now for its teammates' plan (tried again on the tick)."""
        mission_round = self.round
        if not self.fresh_replans or mission_round is None:
            return True
        if mission_round.mission in self._aborted:
            return True
        if teammates_basis is None:
            fallback = mission_round.stands_for()
            if fallback is None or self.uav_id not in MissionRound.survivors(fallback):
                return True
            basis, epoch = fallback.digest, f"epoch {fallback.epoch}"
        else:
            basis = teammates_basis
            epoch = f"of {basis}"
        if basis in self.own.stood:
            return True
        if not self.flight.enabled or self.life.phase in (Phase.ABORTED, Phase.PREEMPTED):
            self.own.stand_none(mission_round, basis)
            self._resolve_ready(now)
            return True
        gps = self.link.gps
        if gps is None or self.link.lost(now):
            if teammates_basis is not None:
                return False  # its first telemetry since a restart may be just ahead
            log.warning(
                "mission %d: no standing for re-plan %s: %s",
                mission_round.mission,
                epoch,
                "no GPS telemetry" if gps is None else "autopilot link lost",
            )
            self.own.stood.add(basis)
            return True
        flying = self.flight.target if self.life.holds_target() else None
        # Its own word is believed of itself only: the targets it reached itself.
        own = self.uav_id
        reached = tuple(sorted(t for t, uav in mission_round.reached_targets.items() if uav == own))
        where = (gps, self.link.wind.value, self.link.smoothed_airspeed())
        if not self.own.start_standing(mission_round, basis, where, flying, reached):
            log.warning(
                "mission %d: the planner refused this UAV's standing", mission_round.mission
            )
        return True

    def on_proposal(self, proposal: PlanProposal, now: float) -> None:
        """A plan proposed for the current mission: kept for the decision, which
        verifies and scores it (fleet.consensus.proposal); after it, changes nothing
        (counted and logged).
        One from a proposer the mission does not entitle is refused and counted, before
        or after the decision (its signature only says who wrote it). One for a later
        mission is kept for when it arrives (onboard.early_proposals), a few at most;
        one for an older mission, or pushed out of those kept, is counted."""
        mission_round = self.round
        if mission_round is None or proposal.mission > mission_round.mission:
            # Its mission may come later (another path, a catch-up): kept till then.
            pushed_out = self._early_proposals.keep(proposal)
            self._no_mission(pushed_out, "pushed out by later proposals")
            return
        if proposal.mission < mission_round.mission:
            self._no_mission([proposal], f"mission {mission_round.mission} superseded it")
            return
        why = mission_round.right_problem(proposal)
        if why is not None:
            DROPPED.add(ProposalRefused.NO_RIGHT)
            _refusals.warn(
                f"mission {proposal.mission}: the plan proposed by {proposal.proposer} "
                f"refused: {why}"
            )
            return
        if mission_round.add_proposal(proposal):
            log.info(
                "mission %d: a plan proposed by %d, to verify at the decision",
                proposal.mission,
                proposal.proposer,
            )
        elif mission_round.committed is not None:
            # After the decision it changes nothing; counted, so that a proposer that is
            # always late (too slow for the window) shows in the UAV's state.
            DROPPED.add(ProposalRefused.LATE)
            _refusals.warn(
                f"mission {proposal.mission}: the plan proposed by {proposal.proposer} "
                "came after the decision: it changes nothing"
            )

    @staticmethod
    def _no_mission(proposals: list[PlanProposal], why: str) -> None:
        """Proposals dropped, not for the mission this UAV holds: counted and logged."""
        for proposal in proposals:
            DROPPED.add(ProposalRefused.NO_MISSION)
            _refusals.warn(
                f"mission {proposal.mission}: the plan proposed by {proposal.proposer} "
                f"dropped, not for the mission held here: {why}"
            )

    def on_assignment(self, report: AssignmentReport, now: float) -> None:
        mission_round = self.round
        if mission_round is None or report.uav == self.uav_id:
            return
        if report.mission != mission_round.mission or report.mission in self._aborted:
            return
        problem = assignment_problem(report, mission_round.latest)
        if problem is not None:
            log.warning(
                "mission %d: UAV %d's assignment refused: %s",
                *(report.mission, report.uav),
                problem,
            )
            return
        if mission_round.committed is None:
            self._adopt(report, now)
        elif (ranked := mission_round.rank_of(report)) is Rank.WEAKER:
            # Two plans of this mission after a heal: the other side re-bases onto ours
            # (fleet.consensus.heal); nothing of its plan, counts included, is taken.
            log.info(
                "mission %d: UAV %d follows a plan built on %d results, ours on %d: "
                "ours stands, it re-bases",
                report.mission,
                report.uav,
                len(report.team),
                len(mission_round.basis_team or ()),
            )
        elif ranked is Rank.STRONGER:
            self._rebase(report, now)
        elif self._merge_membership(mission_round, report):
            self._replan(now)
        elif (resolved := mission_round.adopt_resolved(report)) is not None:
            # A teammate held every survivor's standing: this UAV may have missed one.
            text = (
                f"mission {report.mission}: adopted UAV {report.uav}'s re-plan epoch {report.epoch}"
            )
            self.say(StatusKind.ADOPTED, text, now, mission=report.mission)
            self._apply(resolved, now)
        elif (followed := mission_round.follow(report)) is not None:
            self._apply(followed, now)
        self._settle()

    def _rebase(self, report: AssignmentReport, now: float) -> None:
        """A teammate's plan of this mission wins over ours after a heal
        (fleet.consensus.heal): follow it, keeping what was reached; an append plan
        followed gets this UAV's standing at once (`_apply`), so that the winner's
        re-plan is solved again with it counted in."""
        mission_round = self.round
        assert mission_round is not None
        ours = len(mission_round.basis_team or ())
        rebased = mission_round.rebase(report)
        if rebased is None:
            return
        text = (
            f"mission {report.mission}: two plans after a partition; re-based onto UAV "
            f"{report.uav}'s epoch {report.epoch}, built on {len(report.team)} results "
            f"(ours on {ours})"
        )
        self.say(StatusKind.ADOPTED, text, now, mission=report.mission)
        self._joining = True
        self._apply(rebased, now)

    def _merge_membership(self, mission_round: MissionRound, report: AssignmentReport) -> bool:
        """Take a teammate's membership counts (fleet.consensus.membership); True if the
        re-plan input changed.

        That another UAV dropped out is the reporter's claim about it: believed for the
        reporter itself and for UAVs whose liveliness this UAV saw go. The counts of a UAV
        it counts out that is alive here and did not drop out by its own word (this UAV
        itself included) are left out, a hint: this UAV asks for that UAV's own outcome
        (failed, link lost), which releases it when it says so. The reporter counts it
        back once it sees it alive again, and the counts meet.

        That another UAV asked for a re-plan in changed air is believed from that UAV's
        word alone (fleet.consensus.membership `own_asked`): a report that says so is a
        hint, and this UAV asks that UAV for its standing for the report's append plan,
        which carries its count (`_on_standing` takes it)."""
        claimed = mission_round.asks_claimed(report)
        if claimed:
            log.info(
                "mission %d: UAV %d's re-plan says %s asked for a re-plan in changed air: "
                "asking for their own standings",
                report.mission,
                report.uav,
                ", ".join(map(str, claimed)),
            )
            basis = report.basis or report.digest
            self.outputs.fetch_standings(mission_round.mission, claimed, basis)
        disputed = tuple(
            sorted(
                uav
                for uav in mission_round.counted_out(report) - mission_round.released
                if uav != report.uav and uav in self.team.alive and not self._dropped(uav)
            )
        )
        hinted = tuple(uav for uav in disputed if uav != self.uav_id)
        if hinted:
            log.info(
                "mission %d: UAV %d's re-plan releases %s, still alive here: asking for "
                "their own outcomes",
                report.mission,
                report.uav,
                ", ".join(map(str, hinted)),
            )
            self.outputs.fetch_outcomes(mission_round.mission, hinted)
        return mission_round.merge(report, disputed)

    def _dropped(self, uav: int) -> bool:
        """`uav` left the mission by its own word: its own outcome says it failed or lost
        its link (this UAV: its part ended short)."""
        mission_round = self.round
        assert mission_round is not None
        if uav == self.uav_id:
            outcome = mission_round.outcome
            if outcome is not None and outcome.phase != Phase.REACHED:
                return True
            return self.life.phase in (Phase.FAILED, Phase.PREEMPTED, Phase.ABORTED)
        heard = mission_round.outcomes.get(uav)
        return heard is not None and heard.phase in (Phase.FAILED, Phase.LINK_LOST)

    def _adopt(self, report: AssignmentReport, now: float) -> None:
        assert self.round is not None
        adopted = self.round.adopt(report, self.team.alive, now)
        if adopted is None:
            unused = sorted(self.round.thinner(report, self.team.alive, now))
            log.info(
                "mission %d: UAV %d's assignment not adopted: it was computed without the "
                "results of %s, which this UAV holds",
                report.mission,
                report.uav,
                ", ".join(map(str, unused)),
            )
            return
        text = f"mission {report.mission}: adopted the assignment of UAV {report.uav}"
        self.say(StatusKind.ADOPTED, text, now, mission=report.mission)
        self._apply(adopted, now)
        self._replan_if_released(now)

    def on_outcome(self, outcome: TargetOutcome, now: float) -> None:
        """A teammate reached its target, or dropped out of the mission (failed, link lost)."""
        mission_round = self.round
        if mission_round is None or outcome.uav == self.uav_id:
            return
        if outcome.mission != mission_round.mission:
            return
        # Believed of its own UAV only: what it says a teammate reached is a hint, to be
        # confirmed by that teammate's own outcome (a captured UAV could list ours).
        if claims.newer(mission_round.outcomes.get(outcome.uav), outcome):
            mission_round.outcomes[outcome.uav] = outcome  # relayed, by name, to whoever asks
        mission_round.heard_reached(claims.own_claims(outcome))
        self._fetch_hinted(mission_round, outcome)
        if outcome.phase == Phase.REACHED:
            mission_round.target_reached(outcome.uav, outcome.target)
            self._replan_if_finished(now)
            self._settle()
            return
        dropped = outcome.phase in (Phase.FAILED, Phase.LINK_LOST)
        if dropped and mission_round.release((outcome.uav,)):
            self.say(
                StatusKind.TEAMMATE_DROPPED,
                f"mission {outcome.mission}: UAV {outcome.uav} dropped out "
                f"({outcome.reason or outcome.phase}); re-planning its target",
                now,
                mission=outcome.mission,
                target=outcome.target,
            )
            self._replan(now)
            self._settle()

    def _fetch_hinted(self, mission_round: MissionRound, outcome: TargetOutcome) -> None:
        """Ask, once each, for the own outcomes of the teammates `outcome` says reached a
        target this UAV does not know they reached."""
        asked = mission_round.hints_asked
        wanted = {
            uav
            for target, uav in claims.hints(outcome).items()
            if uav != self.uav_id
            and uav in mission_round.team
            and mission_round.reached_targets.get(target) != uav
            and (uav, target) not in asked
        }
        asked.update((uav, t) for t, uav in claims.hints(outcome).items() if uav in wanted)
        if wanted:
            self.outputs.fetch_outcomes(mission_round.mission, tuple(sorted(wanted)))

    def heard_outcomes(self, mission: int) -> dict[int, TargetOutcome]:
        """Each teammate's latest outcome of `mission` as it signed it (relayed by name)."""
        mission_round = self.round
        if mission_round is None or mission_round.mission != mission:
            return {}
        return mission_round.outcomes

    def on_abort(self, abort: MissionAbort, now: float) -> None:
        """Abort is final: mission m never commits or flies after this, whatever arrives."""
        if abort.uav is not None and abort.uav != self.uav_id:
            return  # a teammate's own abort: this UAV flies on
        self._aborted.add(abort.mission)
        self._abort = abort
        if self.round is None or self.round.mission != abort.mission:
            return
        self._settle()
        if self.life.phase == Phase.ABORTED:
            return
        flying = self.life.holds_target()
        # A resume still pending (a link outage) goes on.
        self.flight.restart(f"mission {abort.mission} aborted", now)
        self.life.observe(Observation.ABORTED)
        course = "back on course" if flying else "it was not flying a target"
        self.say(
            StatusKind.ABORTED,
            f"mission {abort.mission} aborted; {course}",
            now,
            mission=abort.mission,
        )

    # ---- the team's liveliness ---------------------------------------------------------------
    def on_alive(self, uav: int, alive: bool, now: float) -> None:
        if alive:
            if self.team.came(uav):
                self._counted(uav, now)
        elif self.team.went(uav, now, committed=self.decided()):
            self.release_gone(now)  # at once when there is no grace

    def on_spoke(self, uav: int, now: float) -> None:
        """A message signed by `uav` was heard (the secure profile): its token counts."""
        if uav != self.uav_id and self.team.spoke(uav):
            self._counted(uav, now)

    def _counted(self, uav: int, now: float) -> None:
        """A teammate counts as present again (or for the first time)."""
        self.catch_up.request(now)
        self._rejoin(uav, now)

    def _rejoin(self, uav: int, now: float) -> None:
        """A teammate released as lost is alive again (a partition healed, a router or
        the teammate itself restarted): it takes part again from the next epoch."""
        mission_round = self.round
        if mission_round is None or mission_round.committed is None:
            return
        if mission_round.mission in self._aborted or uav not in mission_round.released:
            return
        self._count_back(uav, now, f"UAV {uav} is back; re-planning with it")

    def _count_back(self, uav: int, now: float, why: str) -> None:
        """Count `uav` in again (back from a loss, or in a plan built without it): a new
        epoch, re-planned with it taking part."""
        mission_round = self.round
        assert mission_round is not None
        if mission_round.mission in self._aborted or self._dropped(uav):
            return  # it said it failed or lost its link: alive is not able
        if mission_round.rejoin((uav,)):
            text = f"mission {mission_round.mission}: {why}"
            self.say(StatusKind.REPLANNED, text, now, mission=mission_round.mission)
            self._replan(now)
        self._settle()

    def release_gone(self, now: float) -> None:
        """Release the committed teammates whose liveliness stayed gone past the grace."""
        for uav in self.team.gone_past_grace(now):
            self._release_lost(uav, now)

    def _release_lost(self, uav: int, now: float) -> None:
        mission_round = self.round
        if mission_round is None or mission_round.committed is None:
            return  # before the commitment, the consensus itself leaves it out
        if mission_round.mission in self._aborted:
            return
        if mission_round.release((uav,)):
            self.say(
                StatusKind.TEAMMATE_LOST,
                f"mission {mission_round.mission}: UAV {uav} lost (liveliness gone); "
                "re-planning its target",
                now,
                mission=mission_round.mission,
            )
            self._replan(now)
            self._settle()

    # ---- the decision ------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Fetch the results still missing, and decide once the round is ready; commit a
        re-plan's append plan once its survivors' standings are overdue."""
        mission_round = self.round
        if mission_round is None or mission_round.mission in self._aborted:
            return
        if mission_round.awaiting is not None:
            self._fetch_standings(now)
            self._expire(now)
        self._stand_with_teammates(now)
        if mission_round.committed is not None:
            if mission_round.ask_if_thin(now, self.team.alive):
                self.outputs.fetch_assignments(mission_round.mission)
            self._watch_air(now)
            return
        if self.proposer is not None:
            proposal = self.proposer.tick(mission_round, now)
            if proposal is not None:
                key = self.key_space.uav_proposal(proposal.mission, self.uav_id)
                self.outputs.publish(key, proposal)
                self.on_proposal(proposal, now)
        report = self.decision.tick(mission_round, now)
        if report is not None:
            self._apply(report, now)
            self._replan_if_released(now)

    def _fetch_standings(self, now: float) -> None:
        """Ask the survivors whose standings are still missing a while into the wait
        for them by query (each answers its own, signed), once per append plan."""
        mission_round = self.round
        assert mission_round is not None
        wanted = mission_round.standings_to_fetch(now)
        if wanted is not None:
            basis, uavs = wanted
            self.outputs.fetch_standings(mission_round.mission, uavs, basis)

    def _expire(self, now: float) -> None:
        mission_round = self.round
        assert mission_round is not None
        missing = mission_round.missing_standings()
        report = mission_round.expire(now)
        if report is None:
            return
        self.say(
            StatusKind.REPLANNED,
            f"mission {report.mission}: re-plan epoch {report.epoch}: no fresh times from "
            f"{', '.join(map(str, missing))} in time; their targets appended where reached "
            "earliest",
            now,
            mission=report.mission,
        )
        # Teammates that hold every standing solved it again: asked for, adopted if so.
        self.outputs.fetch_assignments(report.mission)
        self._apply(report, now)

    # ---- the assignment ----------------------------------------------------------------------
    def _replan_if_released(self, now: float) -> None:
        """Teammates released, or the mission changed, before this UAV committed: re-plan
        at once."""
        mission_round = self.round
        if mission_round is None:
            return
        pending = mission_round.pending_change
        if pending is not None and mission_round.committed is not None:
            self._on_change(pending, now)
            return
        if mission_round.base is None:
            return
        if mission_round.behind or mission_round.released & set(mission_round.base.team):
            self._replan(now)

    def _on_change(self, targets: MissionTargets, now: float) -> None:
        """A later revision of the current mission (targets added or removed in flight,
        fleet.consensus.mission_change): a new epoch, re-planned at once."""
        mission_round = self.round
        assert mission_round is not None
        if targets.mission in self._aborted:
            return
        if targets.revision <= mission_round.current.revision:
            return  # a repeat (relayed, or the ground putting it again)
        held = len(mission_round.current.targets)
        problem = targets_problem(targets) or mission_round.amend(targets)
        if problem is not None:
            DROPPED.add(DropReason.INVALID)
            text = (
                f"error: mission {targets.mission} revision {targets.revision} refused: {problem}"
            )
            self.say(StatusKind.MISSION_REFUSED, text, now, mission=targets.mission)
            return
        if mission_round.committed is None:
            return  # taken once committed (`_replan_if_released`)
        added = len(targets.targets) - held
        removed = len(targets.removed)
        text = (
            f"mission {targets.mission}: revision {targets.revision}: {added} target(s) "
            f"added, {removed} removed in all; re-planning"
        )
        self.say(StatusKind.MISSION_CHANGED, text, now, mission=targets.mission)
        if mission_round.base is None:
            # It follows its teammates' epochs: their plan of this revision may have come
            # before the revision itself, refused then for its new target indexes.
            self.outputs.fetch_assignments(targets.mission)
        self._replan(now)
        self._settle()

    def _replan(self, now: float) -> None:
        """Re-assign the targets of released UAVs, or fetch the results that needs."""
        mission_round = self._replannable()
        if mission_round is None:
            return
        report = self.decision.replan(mission_round, now)
        if report is not None:
            self._apply(report, now)
        elif mission_round.awaiting is not None:
            self._stand(now)  # the survivors' standings are awaited: this UAV's too

    def _replan_if_finished(self, now: float) -> None:
        """A UAV may have finished its queue: the append plan awaited or followed hands
        finished UAVs orphans only as the last resort (fleet.consensus.replan), so it is
        computed again, as every teammate computes it once it hears the same arrival
        (an unchanged plan changes nothing). A resolved plan does not depend on it."""
        mission_round = self.round
        if mission_round is not None and mission_round.fallback_moved():
            self._replan(now)

    def _apply(self, report: AssignmentReport, now: float) -> None:
        """Publish the assignment this UAV follows now and fly what it says."""
        self._settle()
        self.outputs.publish(self.key_space.mission_assignment(report.mission, self.uav_id), report)
        if report.epoch > 0:
            # Teammates hear re-plans on a key of their own: the N - 1 epoch-0
            # commitments each UAV would otherwise hear change nothing once it committed
            # (docs/lifecycle.md, "Who hears which assignment").
            self.outputs.publish(self.key_space.mission_replan(report.mission, self.uav_id), report)
            if report.basis is None:
                self._stand(now)  # an append plan: solved again once every standing is in
        self._ask_teammates_standings(report)
        self._follow_air()
        self._fly_plan(report, now)
        self._ask_to_join(report, now)  # once off its old target: it flies none now

    def _fly_plan(self, report: AssignmentReport, now: float) -> None:
        """Fly what the plan followed now says this UAV flies."""
        flight = self.flight
        # The first target of its queue not reached yet: a re-plan keeps a UAV's current
        # target first unless the objective gains, and one done with its queue takes the
        # next.
        wanted = self.round.next_target(self.uav_id) if self.round is not None else None
        if wanted is None and self.life.phase == Phase.REACHED:
            return  # its queue is done, and this plan gives it nothing more
        if wanted == flight.target:
            if wanted is None and self.life.phase in (Phase.COMPUTING, Phase.WAITING):
                self.life.observe(Observation.ASSIGNED_NONE)
                text = f"mission {report.mission}: no target assigned; keeping course"
                self.say(StatusKind.NO_TARGET, text, now, mission=report.mission)
            if wanted is None:
                self._leave_stale_target(now)
            return
        if flight.target is not None and self.life.holds_target():
            # Released, or handed another orphan by a later epoch: off the old target.
            flight.give_up(f"mission {report.mission} epoch {report.epoch}", now)
            self.life.observe(Observation.RELEASED, f"re-planned at epoch {report.epoch}")
        if wanted is None or self.uav_id in report.released:
            flight.hold(None, None)
            self.life.observe(Observation.ASSIGNED_NONE)
            self._leave_stale_target(now)
            return
        self._commit(report, wanted, now)

    def _ask_teammates_standings(self, report: AssignmentReport) -> None:
        """Following its teammates' epochs, this UAV is counted out of the one it took
        (a restart): back, it is counted in again by a re-plan whose standings may have
        been put before it listened. It asks for them (each UAV answers its own, for the
        append plan it waits on) and stands for that plan too (`_on_standing`)."""
        mission_round = self.round
        if not self.fresh_replans or mission_round is None or mission_round.base is not None:
            return
        if self.uav_id in report.released and not self._dropped(self.uav_id):
            self.outputs.fetch_standings(report.mission, (), None)

    # ---- the air the plan was timed in -----------------------------------------------------
    def _aircraft_clock(self) -> float | None:
        """The autopilot's clock (s): mission time, whatever the simulator's speedup."""
        telemetry = self.link.telemetry
        return None if telemetry is None else telemetry.system_time_ms / 1000.0

    def _follow_air(self) -> None:
        """The plan just applied times this UAV's legs in its result's or standing's air."""
        mission_round = self.round
        result = mission_round.air_of(self.uav_id) if mission_round is not None else None
        air = None
        if result is not None and result.wind_east is not None and result.wind_north is not None:
            air = FlyingAir(result.airspeed, Wind(result.wind_east, result.wind_north))
        self.air.follow(air, self._aircraft_clock())

    def _flying_air(self) -> FlyingAir:
        """The air it flies in now, as a result would carry it (the smoothed wind, the
        air data's averaged airspeed clamped to the aircraft's limits)."""
        speed = self.link.air_data_airspeed()
        clamped = None if speed is None else round(_LIMITS.clamp_airspeed(speed), 2)
        return FlyingAir(clamped, self.link.wind.value)

    def _legs_ahead(self) -> bool:
        """It flies a target with more of its queue after it: legs the plan timed ahead."""
        mission_round = self.round
        target = self.flight.target
        if mission_round is None or target is None or not self.life.holds_target():
            return False
        queue = mission_round.queue_of(self.uav_id)
        if target not in queue:
            return False
        rest = queue[queue.index(target) + 1 :]
        return any(
            t not in mission_round.reached_targets and not mission_round.removed(t) for t in rest
        )

    def _leg_begins_soon(self) -> bool:
        """Its target is within BEFORE_LEG_S of its ground speed (straight there): the
        next leg of its queue is about to begin (onboard.air_watch)."""
        gps, distance = self.link.gps, self.flight.target_distance()
        if gps is None or distance is None:
            return False
        speed = math.hypot(gps.vel_east, gps.vel_north)
        return speed > 1.0 and distance <= BEFORE_LEG_S * speed

    def _watch_air(self, now: float) -> None:
        """Ask the team for a re-plan in the air of now when the air moved away from the
        air the plan in force times this UAV's legs in (onboard.air_watch): a new epoch,
        solved again from every UAV's standing (its own carries the ask)."""
        mission_round = self.round
        if not self.fresh_replans or mission_round is None or mission_round.awaiting is not None:
            return
        if mission_round.mission in self._aborted or self.link.lost(now):
            return
        flying = self._flying_air() if self._legs_ahead() else None
        reference = self.air.reference
        # Only a UAV with legs ahead is about to begin one: no distance worked out otherwise.
        before_leg = flying is not None and self._leg_begins_soon()
        if not self.air.check(flying, self._aircraft_clock(), before_leg):
            return
        assert flying is not None and reference is not None
        if not mission_round.ask_air():
            return
        self.say(
            StatusKind.REPLANNED,
            f"mission {mission_round.mission}: the air moved {flying.off_by(reference):.1f} "
            "m/s from the one its plan timed its legs in; asking the team to re-plan in the "
            "air of now",
            now,
            mission=mission_round.mission,
        )
        self._replan(now)
        self._settle()

    def _ask_to_join(self, report: AssignmentReport, now: float) -> None:
        """Re-based onto a plan it takes no part in (the winning side's plan was built
        without it), this UAV gives its standing for it: the UAVs that hold the plan's
        epoch 0 count it in on it (`_count_in`), as they count in a UAV back from a loss,
        and the next epoch solves what is left with it. Without this, it would stay idle
        until some other loss or return made a re-plan."""
        if not self._joining:
            return
        mission_round = self.round
        if mission_round is None or self.uav_id in MissionRound.survivors(report):
            self._joining = False  # counted in (or it holds epoch 0 again): done
            return
        self._teammates_basis = report.digest
        self._stand_with_teammates(now)

    def fly_next(self, now: float) -> None:
        """Its target reached: on to the next target of its queue no UAV reached yet."""
        mission_round = self.round
        if mission_round is None or mission_round.committed is None:
            return
        following = mission_round.next_target(self.uav_id)
        if following is not None and self.life.phase == Phase.REACHED:
            reached = self.flight.target
            seconds = None if reached is None else self._leg_from_here(reached, following)
            self._leg = (mission_round.mission, following, seconds)
            self._commit(mission_round.committed, following, now)

    def _leg_from_here(self, reached: int, following: int) -> float | None:
        """Its time from `reached` (just now) to `following` in the air of the moment: the
        smoothed wind and airspeed, its track in (fleet.consensus.legs.leg_from_here)."""
        assert self.round is not None
        gps, speed = self.link.gps, self.link.smoothed_airspeed()
        if gps is None or speed is None or not AIRSPEED_RANGE[0] <= speed <= AIRSPEED_RANGE[1]:
            return None
        air = Air(speed, self.link.wind.value)
        velocity = (gps.vel_east, gps.vel_north)
        return leg_from_here(self.round.geometry, air, velocity, reached, following)

    def leg_s(self, mission: int, target: int | None) -> float | None:
        """Its time for the leg to `target` of `mission`, timed when it began it: the air
        of that moment for a queue's later target, its result's approach time for the
        first (MissionProgress.leg_s); None where it did not time it."""
        leg = self._leg
        if leg is None or target is None or leg[:2] != (mission, target):
            return None
        return leg[2]

    def _commit(self, report: AssignmentReport, target_index: int, now: float) -> None:
        assert self.round is not None
        if advance(self.life.phase, Observation.ASSIGNED_TARGET) != Phase.COMMITTED:
            self._refuse_orphan(report, target_index, now)
            return
        where = self.round.current.targets[target_index]
        self.flight.commit(report.mission, target_index, where, now)
        eta_s = predicted_arrival(report, self.uav_id, target_index)
        eta = f"{eta_s:.0f} s" if eta_s is not None else "unknown"
        queue = report.queues.get(self.uav_id, ())
        first = not queue or queue[0] == target_index
        if self._leg is None or self._leg[:2] != (report.mission, target_index):
            # Not a queue's next target (fly_next timed those): the consensus's first,
            # whose predicted arrival is the approach time it just computed; a re-plan's
            # is from the results of its start, not from here: not timed.
            fresh = first and report.epoch == 0
            self._leg = (report.mission, target_index, eta_s if fresh else None)
        leg_s = self._leg[2]
        if leg_s is not None and not first:
            eta += f", this leg {leg_s:.0f} s in the wind now"
        self.say(
            StatusKind.TARGET_CHOSEN,
            f"mission {report.mission}: target {target_index} chosen, ETA {eta}",
            now,
            mission=report.mission,
            target=target_index,
        )
        self.life.observe(Observation.ASSIGNED_TARGET)
        if not self.flight.enabled:
            return
        if self.link.awaiting_first(now):
            # Just started (a restart handed its own target again before its first
            # telemetry): written once the autopilot is heard, which routes it from there.
            self._write_awaited = True
            return
        if self.link.lost(now) and report.epoch > 0:
            self._failed("handed an orphaned target while its autopilot link is lost", now)
            return
        self.flight.write_target(report.mission, now)

    def write_awaited(self, now: float) -> None:
        """The first telemetry since the start: write the target held meanwhile."""
        if not self._write_awaited:
            return
        self._write_awaited = False
        if self.life.phase == Phase.COMMITTED and self.round is not None:
            self.flight.write_target(self.round.mission, now)

    def _refuse_orphan(self, report: AssignmentReport, target_index: int, now: float) -> None:
        """A re-plan handed an orphan to a UAV whose part is over (the operator took it
        off its target, or it failed): it does not fly it, and drops out like a failed
        UAV, so that the next epoch hands the orphan on instead of leaving it unflown."""
        why = f"handed target {target_index} at epoch {report.epoch} while {self.life.phase}"
        self.say(
            StatusKind.ORPHAN_REFUSED,
            f"warning: mission {report.mission}: {why}: not flying it",
            now,
            mission=report.mission,
            target=target_index,
        )
        self.publish_outcome(Phase.FAILED, why, target_index)
        if self.round is not None and self.round.release((self.uav_id,)):
            self._replan(now)

    def check_target(self, now: float) -> None:
        """Give up a target the autopilot cannot be made to fly: it is re-planned."""
        if self._write_awaited and not self.link.awaiting_first(now):
            self._write_awaited = False
            if self.life.phase == Phase.COMMITTED:
                why = f"handed a target and no telemetry within {LINK_LOST_S:g} s of the start"
                self._failed(why, now, Phase.LINK_LOST)
            return
        failure = self.flight.failure(now)
        if failure is not None:
            why, cause = failure
            self._failed(why, now, cause)

    def _failed(self, why: str, now: float, cause: Phase = Phase.FAILED) -> None:
        """This UAV cannot fly its target: say so, resume course, and release the target."""
        self.flight.give_up(why, now)
        lost = cause == Phase.LINK_LOST
        self.life.observe(Observation.LINK_LOST if lost else Observation.COMMAND_FAILED, why)
        mission = self.current()
        self.say(
            StatusKind.CANNOT_FLY,
            f"error: mission {'?' if mission is None else mission}: "
            f"cannot fly target {self.flight.target}: {why}",
            now,
            mission=mission,
            target=self.flight.target,
        )
        self.publish_outcome(cause, why, self.flight.target)
        if self.round is not None and self.round.release((self.uav_id,)):
            self._replan(now)

    def abort_of(self, mission: int) -> MissionAbort | None:
        """The abort of `mission` this UAV obeyed, for a teammate that missed it."""
        if self._abort is None or self._abort.mission != mission:
            return None
        return self._abort
