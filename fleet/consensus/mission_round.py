"""One mission's distributed target assignment, as one UAV sees it (thesis 4.4, hardened).

The thesis assumed lossless links and every UAV in range. Here:

* the team is the one the ground named, less the UAVs not alive (liveliness);
* a UAV commits as soon as it holds the result of every live teammate, or at the
  mission's deadline with whatever it holds (missing results are fetched by query
  first, by the caller, `FETCH_INTERVAL` seconds after the last result heard, and at
  least one interval before the deadline);
* a committed assignment seen from a teammate is adopted as is, if it is not thinner
  than what this UAV holds: it must have been computed from at least the results of
  the live teammates this UAV holds (else this UAV commits its own and the digests
  disagree, visibly). "First committed wins" makes late joiners and restarted UAVs
  (which hold no result yet) fall in line;
* teammates' commitments are not heard live (only their re-plans are): a UAV asks for
  them by query when its own decision might not be the team's (`must_ask`), and waits
  `ASK_GRACE_S` for the answers before it decides;
* every commitment carries the digest of the exact results it used, so the ground can
  confirm agreement or name who disagreed;
* after the commitment, team UAVs that drop out are *released* and their targets
  re-planned: each re-plan is a new epoch of the same mission, published under the same
  key, solved again from every survivor's standing (`fleet.consensus.resolve`) or,
  when one is missing after STANDINGS_WAIT_S, the append plan (`fleet.consensus.replan`).

Pure: no I/O, time comes in as `now`.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import dataclass, field

import msgspec

from fleet.consensus.assignment import air_bytes, proposes_bytes, results_digest
from fleet.consensus.heal import Rank, rank
from fleet.consensus.legs import Air, AirLegs, LegGeometry, leg_times
from fleet.consensus.membership import (
    Membership,
    membership_digest,
    own_asked,
    report_counts,
)
from fleet.consensus.mission_change import (
    added_targets,
    change_digest,
    change_problem,
    estimated_times,
    planned_count,
)
from fleet.consensus.objectives import plan_digest, plan_queues
from fleet.consensus.proposal import (
    awaited_proposers,
    choose,
    proposal_digest,
    proposal_problem,
    right_problem,
)
from fleet.consensus.queues import UNREACHABLE
from fleet.consensus.replan import candidates, finished_digest, missing_times, replan
from fleet.consensus.report_checks import (
    assignment_problem,
    predicted_arrival,
    queues_problem,
    targets_problem,
    team_set,
)
from fleet.consensus.resolve import (
    NO_TAKER,
    Standing,
    remaining_targets,
    resolve,
    resolve_digest,
)
from fleet.consensus.result_rows import ResultRows
from fleet.mission.messages import (
    AssignmentHeader,
    AssignmentReport,
    MissionTargets,
    PlanProposal,
    TargetOutcome,
    UavResult,
)
from fleet.mission.no_fly import zones_bytes

__all__ = [
    "MissionRound",
    "Settled",
    "assignment_problem",
    "predicted_arrival",
    "queues_problem",
    "targets_problem",
]

FETCH_INTERVAL = 1.0
#: A teammate's assignment that arrives this soon (s) after this UAV started the round
#: was committed before it joined: adopted even without this UAV's result in it.
JOIN_GRACE_S = 1.0
#: A UAV whose decision might not be the team's (`MissionRound.must_ask`) asks the team
#: what it decided and waits this long (s) for the answers before it decides.
ASK_GRACE_S = 0.5
#: A re-plan waits this long (s) for every survivor's standing (its fresh times from
#: where it is now) before it commits the epoch's append plan instead.
STANDINGS_WAIT_S = 3.0
#: Standings are kept for this many epochs' bases at most (the newest).
STANDING_BASES = 8
#: A UAV that committed on a plan built without some live teammates' results asks the
#: team what it decided this often (s), at most THIN_ASKS times a basis: a stronger plan
#: of theirs is re-based onto (fleet.consensus.heal). Their epoch-0 commitments are not
#: heard live, and without a later re-plan nothing else would tell it.
THIN_ASK_S = 2.0
THIN_ASKS = 15


@dataclass(frozen=True, slots=True)
class Settled:
    """What a UAV has settled of its mission: enough to tell, from an assignment
    report's header alone (`AssignmentHeader`), that the report changes nothing for it.

    Every part only grows while the UAV runs (the mission id, the commitment, the abort,
    the released UAVs, the epoch followed), so a report an older snapshot
    `covers` changes nothing under the UAV's later state either: a bus thread may check
    reports against a snapshot while the main loop moves on.
    """

    mission: int
    own_id: int
    committed: bool
    aborted: bool
    team: frozenset[int]
    #: Team UAVs released: a report releasing them again changes nothing.
    done: frozenset[int]
    #: Without epoch 0 (`MissionRound.base` None), the epoch followed: a later one is
    #: taken (`MissionRound.follow`). None with epoch 0: later epochs are re-planned
    #: from the released set alone.
    following: int | None
    #: The membership counts (fleet.consensus.membership): a report whose counts are no
    #: larger changes nothing.
    left: tuple[tuple[int, int], ...] = ()
    back: tuple[tuple[int, int], ...] = ()
    asked: tuple[tuple[int, int], ...] = ()
    #: The mission's revision this UAV holds: a report of a later one may change it.
    revision: int = 0
    #: The append plan whose resolved plan this UAV follows (its digest), None if none:
    #: a teammate's resolved plan of another basis may change its plan.
    resolved: str | None = None
    #: The epoch-0 team the plan followed is built on (`MissionRound.basis_team`): a
    #: report of a plan built on another may be the one the team keeps after a heal
    #: (fleet.consensus.heal).
    basis_team: tuple[int, ...] = ()

    def covers(self, header: AssignmentHeader) -> bool:
        """True if the report `header` heads changes nothing for this UAV."""
        if header.mission != self.mission:
            return header.mission < self.mission  # an older mission's; a newer may start
        if header.uav == self.own_id or self.aborted:
            return True
        if not self.committed:
            return False  # it may be adopted
        if header.team and self.basis_team and rank(header.team, self.basis_team) != Rank.SAME:
            return False  # two plans of one mission after a heal: one wins
        if header.basis is not None and header.basis != self.resolved:
            return False  # a resolved plan this UAV may be waiting for
        if self.following is not None and header.epoch > self.following:
            return False
        if header.revision > self.revision:
            return False
        if header.left or header.back or header.asked:
            # Another UAV's ask beyond ours is not believed from the header's author, but
            # is not covered either: a hint, whose asker's own word the module asks for.
            left, back = report_counts(header.released, header.left, header.back)
            view = Membership(self.team, dict(self.left), dict(self.back), dict(self.asked))
            return view.covers(left, back, header.asked)
        released = header.released
        return not released or all(uav in self.done or uav not in self.team for uav in released)


@dataclass
class MissionRound:
    targets: MissionTargets
    own_id: int
    started: float
    #: Learnt from a catch-up (a late join, a restart) or just after this UAV was
    #: suspended, not as it was sent: the team may have decided already, maybe with
    #: this UAV's result from before a restart.
    late: bool = False
    #: This UAV was suspended (frozen) while the round was open: what the team decided
    #: or the ground aborted meanwhile may still wait in its bus session's backlog,
    #: behind the results it handled first (`must_ask`).
    resumed: bool = False
    results: dict[int, UavResult] = field(default_factory=dict)
    #: The assignment this UAV follows now: epoch 0, or the latest re-plan.
    committed: AssignmentReport | None = None
    last_fetch: float | None = None
    #: When this UAV asked its teammates what they decided (`must_ask`); None before.
    asked_at: float | None = None
    #: The epoch-0 assignment every re-plan starts from; None when this UAV adopted a
    #: re-plan without knowing epoch 0, or epoch 0 without the own result it was
    #: computed from (a restart): it then follows its teammates' epochs.
    base: AssignmentReport | None = None
    #: Who is out of the mission after the commitment, as counts that only grow: a UAV
    #: that comes back is in again (fleet.consensus.membership).
    membership: Membership = field(init=False, repr=False, compare=False)
    #: Team UAVs that reached every target of their queue. Released like any other when
    #: they go (liveliness), so that a later epoch never hands them an orphan.
    reached: set[int] = field(default_factory=set)
    #: Targets some UAV reported reaching, and by whom: skipped when a queue comes to them.
    reached_targets: dict[int, int] = field(default_factory=dict)
    #: How this UAV's own part ended (reached), or why it dropped out; None before.
    outcome: TargetOutcome | None = None
    #: Each teammate's latest outcome as it signed it, relayed to whoever asks by name.
    outcomes: dict[int, TargetOutcome] = field(default_factory=dict)
    #: (UAV, target) pairs a teammate's outcome named reached whose own outcome this
    #: UAV asked for (once each: a claim about another UAV is a hint, not a fact).
    hints_asked: set[tuple[int, int]] = field(default_factory=set)
    #: (UAV, count): asks for a re-plan in changed air a teammate's report said another
    #: UAV made, beyond what this UAV counts, whose asker's own word this UAV asked for
    #: (once each: an ask is believed from its asker alone, `asks_claimed`).
    asks_hinted: set[tuple[int, int]] = field(default_factory=set)
    #: The team as a set (membership is asked of every message heard).
    team: frozenset[int] = field(init=False, repr=False, compare=False)
    #: Each result's greedy order and digest bytes, computed as it arrives.
    rows: ResultRows = field(default_factory=ResultRows, repr=False, compare=False)
    #: Plans proposed for this mission before the decision, by proposer (the latest).
    proposals: dict[int, PlanProposal] = field(default_factory=dict)
    #: Why each proposal refused at the decision was refused (proposer -> why).
    refused_proposals: dict[int, str] = field(default_factory=dict)
    #: The mission's latest revision this UAV took after its commitment (changed in
    #: flight: fleet.consensus.mission_change); None: as first sent (`targets`).
    change: MissionTargets | None = None
    #: A later revision heard before the commitment: taken once committed.
    pending_change: MissionTargets | None = None
    #: Re-plans are solved again from the survivors' standings (fleet.consensus.resolve);
    #: off, every re-plan is the append rule's, committed at once.
    resolving: bool = False
    #: Each survivor's standing (a `UavResult` with a `basis`), by basis, then by UAV: the
    #: first heard of each.
    standings: dict[str, dict[int, UavResult]] = field(default_factory=dict)
    #: The epoch's append plan, not committed: waiting for the survivors' standings.
    awaiting: AssignmentReport | None = None
    #: When this UAV started waiting for them.
    awaiting_since: float | None = None
    #: The append plans (digests) whose missing standings this UAV asked for by query
    #: (once each, FETCH_INTERVAL into the wait: `standings_to_fetch`).
    standings_asked: set[str] = field(default_factory=set)
    #: The basis (epoch-0 team) this UAV last asked about as thin (`ask_if_thin`), when,
    #: and how often.
    thin_asked: tuple[tuple[int, ...], float, int] | None = None

    def __post_init__(self) -> None:
        self.team = team_set(self.targets.team)
        self.membership = Membership(self.team)

    @property
    def current(self) -> MissionTargets:
        """The mission as it stands now: its latest revision taken, else as first sent."""
        return self.change if self.change is not None else self.targets

    def amend(self, new: MissionTargets) -> str | None:
        """Take a later revision of the mission (after the commitment; before it, kept
        for then); why not, if it is not one."""
        held = self.current if self.committed is not None else self.pending_change
        problem = change_problem(held or self.current, new)
        if problem is not None:
            return problem
        if self.committed is None:
            self.pending_change = new
            return None
        self._take(new)
        return None

    @property
    def latest(self) -> MissionTargets:
        """The latest revision heard: a teammate's plan may be of it already."""
        return self.pending_change or self.current

    def _take(self, new: MissionTargets) -> None:
        self.pending_change = None
        self.change = new
        for cached in ("legs", "geometry"):  # now over the added targets too
            self.__dict__.pop(cached, None)

    @property
    def behind(self) -> bool:
        """The plan followed is of an earlier revision than the one taken."""
        committed = self.committed
        return committed is not None and committed.revision < self.current.revision

    def removed(self, target: int) -> bool:
        return target in self.current.removed

    @property
    def released(self) -> set[int]:
        """Team UAVs out of the mission now (dropped out, and not back since)."""
        return set(self.membership.out())

    @functools.cached_property
    def legs(self) -> list[list[float]]:
        """Target-to-target times in still air, from the mission alone: one table for
        every UAV, what a target's neighbours are found by (fleet.consensus.legs)."""
        return leg_times(self.current.targets, zones=self.targets.zones)

    @functools.cached_property
    def geometry(self) -> LegGeometry:
        """Every leg's length and direction (and route round the zones), from the mission
        alone: each UAV's legs are timed from it in its own air."""
        return LegGeometry.of(self.current.targets, self.targets.zones)

    def prepare(self) -> list[list[float]]:
        """The legs' geometry and the still-air table, computed now (while the approach
        times are planned), not when every UAV decides at once on the last result: the
        consensus window."""
        _ = self.geometry
        return self.legs

    def air_legs(self, uavs: Iterable[int]) -> AirLegs:
        """Each of `uavs`' legs in the air its result says it flies in (its airspeed and
        smoothed wind, digested with its times)."""
        air = {uav: Air.of(self.results[uav]) for uav in uavs if uav in self.results}
        return AirLegs(self.geometry, air, self.legs)

    def _air_bytes(self, uavs: Iterable[int]) -> dict[int, bytes]:
        out = {}
        for uav in uavs:
            r = self.results[uav]
            out[uav] = air_bytes(uav, (r.airspeed, r.wind_east, r.wind_north, r.lat, r.lon))
        return out

    def queue_of(self, uav: int) -> tuple[int, ...]:
        """`uav`'s queue in the plan this UAV follows (empty before the commitment)."""
        report = self.committed
        if report is None or uav in report.released:
            return ()
        if report.queues:
            return report.queues.get(uav, ())
        return (report.pairs[uav],) if uav in report.pairs else ()

    def next_target(self, uav: int) -> int | None:
        """The first target of `uav`'s queue no UAV has reported reaching (None: done)."""
        for target in self.queue_of(uav):
            if target not in self.reached_targets and not self.removed(target):
                return target
        return None

    def target_reached(self, uav: int, target: int | None) -> None:
        """`uav` reported reaching `target`: skipped by whoever's queue comes to it."""
        if target is not None:
            self.reached_targets.setdefault(target, uav)
        self._update_reached()

    def heard_reached(self, reached: dict[int, int]) -> None:
        """A teammate's outcome listed these targets reached (target -> by whom)."""
        count = len(self.current.targets)
        for target, uav in reached.items():
            if target < count and uav in self.team:
                self.reached_targets.setdefault(target, uav)
        self._update_reached()

    def finished(self) -> frozenset[int]:
        """Team UAVs done with the mission for now: each reached a target itself and
        nothing of its queue in the plan followed is left. The append plan hands them an
        orphan only as the last resort (fleet.consensus.replan); a UAV idle from the
        start, which flew nothing, is not finished."""
        flew = set(self.reached_targets.values())
        return frozenset(u for u in flew & self.team if self.next_target(u) is None)

    def _update_reached(self) -> None:
        reached = self.reached_targets.keys()
        if not reached:  # at the commitment: nobody is done, no need to ask N queues
            self.reached = set()
            return
        self.reached = {uav for uav in self.team if (q := self.queue_of(uav)) and reached >= set(q)}

    @property
    def mission(self) -> int:
        return self.targets.mission

    @property
    def deadline(self) -> float:
        return self.started + self.targets.deadline_s

    def settled(self, aborted: bool) -> Settled:
        """This UAV's standing in the mission (`aborted`: the mission was aborted)."""
        committed = self.committed
        return Settled(
            mission=self.mission,
            own_id=self.own_id,
            committed=committed is not None,
            aborted=aborted,
            team=self.team,
            done=frozenset(self.released),
            left=tuple(sorted(self.membership.left.items())),
            back=tuple(sorted(self.membership.back.items())),
            asked=tuple(sorted(self.membership.asked.items())),
            following=committed.epoch if committed is not None and self.base is None else None,
            revision=self.current.revision,
            resolved=committed.basis if committed is not None else None,
            basis_team=self.basis_team or (),
        )

    def add_result(self, result: UavResult) -> bool:
        """Keep a teammate's (or our own) result; False if it is not for this round."""
        if result.mission != self.mission or result.uav not in self.team:
            return False
        if len(result.times) != planned_count(self.targets):
            return False
        if self.committed is not None and result.uav in self.results:
            # Re-plans use the epoch-0 results: a restarted teammate's new times would
            # give UAVs that heard them other pairs under the same digest.
            return False
        self.results[result.uav] = result
        self.rows.add(result.uav, result.times)
        return True

    def heard(self, now: float) -> None:
        """A teammate's result arrived by publication: while results keep coming, the
        next fetch of the missing ones waits (FETCH_INTERVAL after the latest), but it
        still comes at least one interval before the deadline, when they are due."""
        if self.committed is not None or self.last_fetch is None:
            return
        latest = self.deadline - 2 * FETCH_INTERVAL
        self.last_fetch = max(self.last_fetch, min(now, latest))

    def expected(self, alive: set[int]) -> set[int]:
        """Teammates whose results this UAV still waits for or holds."""
        return {uav for uav in self.targets.team if uav in alive or uav == self.own_id}

    def missing(self, alive: set[int]) -> set[int]:
        return self.expected(alive) - self.results.keys()

    def ready(self, now: float, alive: set[int]) -> bool:
        if self.committed is not None or self.own_id not in self.results:
            return False
        if now >= self.deadline:
            return True
        return not self.missing(alive) and not self.awaiting_proposal(now, alive)

    def awaiting_proposal(self, now: float, alive: set[int] | None = None) -> bool:
        """The mission expects a proposed plan (`proposals_s`), its window is still open,
        and a proposal that could be adopted now is still to come: a valid one from each
        proposer the mission names and entitles (a named UAV outside the team is not
        waited for, nor one whose result says it will not propose), or any valid one if
        it names none. A decision that would leave a team UAV out (gone by `alive`;
        None: every team UAV alive) waits for none: each proposal is solved from every
        team UAV's result, so none could be adopted (fleet.consensus.proposal). An
        invalid proposal does not close the window."""
        window = self.targets.proposals_s
        if window <= 0.0 or now >= self.started + window:
            return False
        gone = self.team - alive - {self.own_id} if alive is not None else frozenset()
        used = {
            uav: result.times
            for uav, result in self.results.items()
            if alive is None or uav in alive or uav == self.own_id
        }
        # Named UAVs whose results (the ones decided on) say they will not propose.
        silent = {uav for uav in used if self.results[uav].proposes is False}
        awaited = awaited_proposers(self.targets.proposers, self.team, gone, silent)
        if awaited is not None and not awaited:
            return False
        if not self.proposals:
            return True
        legs = self.air_legs(used)
        inputs = self.results_digest(used)
        objective = self.targets.objective
        valid = {
            proposer
            for proposer, p in self.proposals.items()
            if proposal_problem(p, self.mission, objective, inputs, used, legs) is None
        }
        # Named proposers: every one's valid proposal, so that every UAV chooses among
        # the same ones (the first to come would differ from UAV to UAV).
        return not awaited <= valid if awaited is not None else not valid

    def right_problem(self, proposal: PlanProposal) -> str | None:
        """Why `proposal`'s proposer may not propose for this mission; None if it may."""
        return right_problem(proposal.proposer, self.targets.proposers, self.team)

    def add_proposal(self, proposal: PlanProposal) -> bool:
        """Keep a proposed plan for this round's decision; False if it is another
        mission's, from a proposer the mission does not entitle (`right_problem`), or
        came after the commitment (a late proposal changes nothing)."""
        if proposal.mission != self.mission or self.committed is not None:
            return False
        if self.right_problem(proposal) is not None:
            return False
        self.proposals[proposal.proposer] = proposal
        return True

    def results_digest(self, used: dict[int, tuple[float | None, ...]]) -> str:
        """The digest of exactly these results, as the decision computes it."""
        proposes = {uav: proposes_bytes(uav, self.results[uav].proposes) for uav in used}
        return results_digest(
            used,
            zones_bytes(self.targets.zones),
            self.rows.packed(used),
            self._air_bytes(used),
            proposes,
        )

    def excluded(self, alive: set[int]) -> frozenset[int]:
        """Team UAVs whose results a decision now would leave out (missing, or gone)."""
        used = {uav for uav in self.results if uav in alive or uav == self.own_id}
        return self.team - used

    def must_ask(self, alive: set[int]) -> bool:
        """Whether this UAV's own decision now might not be its teammates': it would
        leave a team UAV's result out (a teammate may hold it and have committed with
        it), or the round was learnt late (by catch-up, or after a freeze: the team may
        have committed without this UAV, or with its result from before a restart), or
        it was open across a freeze (`resumed`: a commitment or an abort sent meanwhile
        may still be queued behind the results handled first; the question's answers
        come after that backlog). Teammates' commitments are not heard live, so such a
        UAV asks for them before it decides, and adopts one that is not thinner than
        what it holds. A UAV that holds every team UAV's result, heard live, decides
        what its teammates decide from the same results."""
        return self.late or self.resumed or bool(self.excluded(alive))

    def resume(self, now: float) -> None:
        """This UAV was suspended: an undecided round asks the team what it decided before
        deciding (`must_ask`), and waits ASK_GRACE_S for the answers (`asking`), which
        come after the bus session's backlog, so that an abort or a commitment sent
        meanwhile is handled before it decides. The question is asked when the round is
        ready, not here: the catch-up the resume sent may go out before the session has
        reconnected (past Zenoh's lease), and a question with no answer would let it
        decide alone once the grace ran out."""
        if self.committed is None:
            self.resumed = True

    def ask_if_thin(self, now: float, alive: set[int]) -> bool:
        """Whether to ask the team what it decided now: this UAV follows a plan built
        without some teammates alive here (a thin commitment after a deadline), every
        THIN_ASK_S, THIN_ASKS times for one basis at most (a teammate that never commits
        is not asked about forever)."""
        basis = self.basis_team
        if basis is None or not (self.team & alive) - set(basis) - {self.own_id}:
            return False
        if self.thin_asked is not None and self.thin_asked[0] == basis:
            _, at, count = self.thin_asked
            if count >= THIN_ASKS or now - at < THIN_ASK_S:
                return False
            self.thin_asked = (basis, now, count + 1)
            return True
        self.thin_asked = (basis, now, 1)
        return True

    def asking(self, now: float) -> bool:
        """Still waiting for the answers to the question `must_ask` called for."""
        return self.asked_at is not None and now - self.asked_at < ASK_GRACE_S

    def should_fetch(self, now: float, alive: set[int]) -> bool:
        """Time to query the results we have not heard published."""
        if self.committed is not None or not self.missing(alive):
            return False
        if self.own_id not in self.results:
            return False
        return self.last_fetch is None or now - self.last_fetch >= FETCH_INTERVAL

    def decide(self, alive: set[int]) -> AssignmentReport:
        """Run the greedy on the results of the live teammates held now, and commit."""
        used = {
            uav: result.times
            for uav, result in self.results.items()
            if uav in alive or uav == self.own_id
        }
        objective = self.targets.objective
        legs = self.air_legs(used)
        plan = plan_queues(used, legs, objective, self.rows.orders(used))
        inputs = self.results_digest(used)
        digest = plan_digest(inputs, objective)
        if self.proposals:
            valid = []
            for proposer, proposal in sorted(self.proposals.items()):
                problem = proposal_problem(proposal, self.mission, objective, inputs, used, legs)
                if problem is None:
                    valid.append(proposal)
                else:
                    self.refused_proposals[proposer] = problem
            plan, adopted = choose(plan, valid, objective, used, legs)
            if adopted is not None:
                digest = proposal_digest(digest, adopted)
        heads = plan.heads()
        self.committed = self.base = self._report(
            target=heads.get(self.own_id),
            pairs=heads,
            queues={uav: q for uav, q in plan.queues.items() if q},
            arrivals={uav: a for uav, a in plan.arrivals.items() if a},
            unserved={t: UNREACHABLE for t in plan.unassigned},
            team=tuple(sorted(used)),
            digest=digest,
        )
        self._update_reached()
        return self.committed

    def _report(
        self,
        *,
        target: int | None,
        pairs: dict[int, int],
        queues: dict[int, tuple[int, ...]],
        arrivals: dict[int, tuple[float, ...]],
        unserved: dict[int, str],
        team: tuple[int, ...],
        digest: str,
        epoch: int = 0,
        released: tuple[int, ...] = (),
        left: dict[int, int] | None = None,
        back: dict[int, int] | None = None,
        revision: int = 0,
        basis: str | None = None,
        asked: dict[int, int] | None = None,
    ) -> AssignmentReport:
        """This UAV's report of a plan; its ETA is its first target's arrival."""
        own = arrivals.get(self.own_id, ())
        return AssignmentReport(
            mission=self.mission,
            uav=self.own_id,
            target=target,
            pairs=dict(sorted(pairs.items())),
            unassigned=tuple(sorted(unserved)),
            team=team,
            digest=digest,
            eta_s=own[0] if own else None,
            epoch=epoch,
            released=released,
            queues=dict(sorted(queues.items())),
            arrivals=dict(sorted(arrivals.items())),
            objective=self.targets.objective,
            unserved=dict(sorted(unserved.items())),
            left=left or {},
            back=back or {},
            revision=revision,
            basis=basis,
            asked=asked or {},
        )

    def thinner(self, report: AssignmentReport, alive: set[int], now: float) -> set[int]:
        """Live UAVs whose results this UAV holds, or is computing, but `report` was
        computed without.

        Its own result counts while it is still being computed, once the round is older
        than JOIN_GRACE_S: a report that arrives within that grace was committed before
        this UAV even started, and is adopted. In a round learnt late (a late joiner, a
        restart, a UAV back from a freeze) its own result never counts: the team may
        have decided without it while it was away, and an answer that comes after
        JOIN_GRACE_S (a loaded machine) is still adopted.
        """
        # A result with no time at all (a UAV that declined) changes no pair.
        held = {
            uav
            for uav, result in self.results.items()
            if (uav in alive or uav == self.own_id) and any(t is not None for t in result.times)
        }
        if self.late:
            held.discard(self.own_id)
        elif self.own_id not in self.results and now - self.started > JOIN_GRACE_S:
            held.add(self.own_id)
        return held - set(report.team)

    def adopt(
        self, report: AssignmentReport, alive: set[int], now: float
    ) -> AssignmentReport | None:
        """Take a teammate's committed assignment as ours; None if we committed already
        or if the report is thinner than what we hold (`thinner`)."""
        if self.committed is not None or report.mission != self.mission:
            return None
        if self.thinner(report, alive, now):
            return None
        if self.pending_change is not None:  # committed from now: its targets too
            self._take(self.pending_change)
        self.committed = self._own_copy(report)
        # A re-plan needs this UAV's own epoch-0 times if epoch 0 used them; a restarted
        # UAV lost them (nobody else answers for them), so it follows its teammates'
        # epochs instead of waiting for them forever.
        if report.epoch == 0 and (self.own_id in self.results or self.own_id not in report.team):
            self.base = self.committed
        self.membership.merge(*_counts(report))
        return self.committed

    def follow(self, report: AssignmentReport) -> AssignmentReport | None:
        """Without epoch 0, take a teammate's later epoch as ours (None if not later)."""
        if self.base is not None or self.committed is None or report.mission != self.mission:
            return None
        if report.epoch <= self.committed.epoch:
            return None
        self.membership.merge(*_counts(report))
        self.committed = self._own_copy(report)
        return self.committed

    @property
    def basis_team(self) -> tuple[int, ...] | None:
        """The epoch-0 team the plan this UAV follows is built on: its epoch 0's, else
        (following its teammates' epochs) the followed plan's; None before it commits."""
        if self.base is not None:
            return self.base.team
        return self.committed.team if self.committed is not None else None

    def rank_of(self, report: AssignmentReport) -> Rank:
        """How a teammate's committed plan of this mission ranks against the one this UAV
        follows (fleet.consensus.heal); SAME before this UAV commits."""
        ours = self.basis_team
        if ours is None or report.mission != self.mission:
            return Rank.SAME
        return rank(report.team, ours)

    def rebase(self, report: AssignmentReport) -> AssignmentReport | None:
        """Two plans of this mission met after a heal and `report`'s wins (`rank_of`):
        follow it from now on, as a UAV without epoch 0 follows its teammates' epochs.

        This UAV's epoch 0, its re-plan awaited and its membership counts (all of the
        losing plan) go; the targets reached stay reached (arrivals are facts) and are
        skipped by whoever's queue comes to them; its standing for the winner's next
        re-plan counts it in there. None if `report` does not win."""
        if self.committed is None or self.rank_of(report) != Rank.STRONGER:
            return None
        self.base = None
        self.awaiting = self.awaiting_since = None
        self.membership = Membership(self.team)
        self.membership.merge(*_counts(report))
        return self._own_copy(report)

    def _own_copy(self, report: AssignmentReport) -> AssignmentReport:
        target = report.pairs.get(self.own_id)
        own = self.results.get(self.own_id)
        eta = own.times[target] if own is not None and target is not None else None
        if report.arrivals.get(self.own_id):
            eta = report.arrivals[self.own_id][0]
        copy = msgspec.structs.replace(report, uav=self.own_id, target=target, eta_s=eta)
        self.committed = copy
        self._update_reached()
        return copy

    # ---- after the commitment ---------------------------------------------------------
    def release(self, uavs: Iterable[int]) -> bool:
        """Mark team UAVs as out of the mission; True if that changes the re-plan input."""
        # A UAV done with its queue is released too when it goes: it holds nothing a
        # later epoch may hand it, and every teammate releases it alike (liveliness).
        new = self.membership.leave(uavs)
        if self.base is None:
            return False
        # A UAV counted in since epoch 0 may hold targets of a resolved plan: its going
        # is a new epoch like a base UAV's (it was in: `leave` changes only those).
        return any(uav in self.base.team or self.membership.back.get(uav) for uav in new)

    def rejoin(self, uavs: Iterable[int]) -> bool:
        """Team UAVs out of the mission came back (alive again), or UAVs the epoch-0 plan
        was built without are counted in (a side that re-based onto this plan after a
        heal, `joinable`): in from the next epoch, which solves what is left with their
        standings (`survivors`). True if that changes the re-plan input."""
        uavs = tuple(uavs)
        back = self.membership.come_back(uavs)
        if self.base is None:
            return False
        base_team = set(self.base.team)
        joined = self.membership.join(uav for uav in uavs if uav not in base_team)
        return bool(back or joined)

    def joinable(self, uav: int) -> bool:
        """`uav` is a team UAV the plan was built without, never counted in or out since:
        counted in by `rejoin` when it stands for this plan (it re-based onto it)."""
        base = self.base
        if base is None or uav not in self.team or uav in base.team:
            return False
        membership = self.membership
        return not membership.left.get(uav) and not membership.back.get(uav)

    def asks_claimed(self, report: AssignmentReport) -> tuple[int, ...]:
        """Teammates other than its author that `report` says asked for more re-plans in
        changed air than this UAV counts, not asked about yet for that count: a hint,
        not a fact (fleet.consensus.membership `own_asked`). Their own word (a standing
        that carries their count) is to be asked for; marked asked here."""
        counted = self.membership.asked
        claimed = tuple(
            sorted(
                uav
                for uav, count in report.asked.items()
                if uav not in (report.uav, self.own_id)
                and uav in self.team
                and count > counted.get(uav, 0)
                and (uav, count) not in self.asks_hinted
            )
        )
        self.asks_hinted.update((uav, report.asked[uav]) for uav in claimed)
        return claimed

    def counted_out(self, report: AssignmentReport) -> set[int]:
        """The team UAVs a teammate's report counts out of the mission."""
        left, back = report_counts(report.released, report.left, report.back)
        return {uav for uav, n in left.items() if n > back.get(uav, 0) and uav in self.team}

    def merge(self, report: AssignmentReport, disputed: Iterable[int] = ()) -> bool:
        """Take a teammate's membership counts (the larger of each), but none about the
        `disputed` UAVs; True if that changes the re-plan input."""
        left, back, asked = _counts(report)
        for uav in disputed:
            left.pop(uav, None)
            back.pop(uav, None)
        changed = self.membership.merge(left, back, asked)
        return changed and self.base is not None

    def ask_air(self) -> bool:
        """This UAV asks its team to re-plan in the air of now (its smoothed wind or
        airspeed moved away from the air its plan timed its legs in: onboard.air_watch):
        one more `asked` count of its own, a new epoch (fleet.consensus.membership). False
        where it cannot: before the commitment, without epoch 0 (following its teammates'
        epochs, it has no append plan to stand for), with re-plans not solved again from
        standings (the append plan of an epoch nobody left is epoch 0's again), or out of
        the mission."""
        if self.committed is None or self.base is None or not self.resolving:
            return False
        if self.membership.is_out(self.own_id):
            return False
        return self.membership.ask(self.own_id)

    def take_asked(self, uav: int, asked: int) -> bool:
        """A teammate's standing says it asked for `asked` re-plans in changed air (its
        own word, of itself): taken if more than counted here; True if that changes the
        re-plan input."""
        if uav == self.own_id or asked <= 0:
            return False
        changed = self.membership.merge({}, {}, {uav: asked})
        return changed and self.base is not None

    def air_of(self, uav: int) -> UavResult | None:
        """The result whose air (airspeed, wind) times `uav`'s legs in the plan this UAV
        follows: its standing for a resolved re-plan, else its epoch-0 result (the
        append plan's legs are timed in the epoch-0 results' air); None if not held."""
        committed = self.committed
        if committed is not None and committed.basis is not None:
            return self.standings.get(committed.basis, {}).get(uav)
        return self.results.get(uav)

    def replan_missing(self) -> tuple[int, ...]:
        """Candidates whose results a re-plan needs and this UAV lacks."""
        if self.base is None:
            return ()
        times = self._times()
        if self.change is not None:  # added or removed targets move every queue
            return tuple(u for u in candidates(self.base, self.released) if u not in times)
        return missing_times(self.base, times, self.released)

    def replan(self, now: float = 0.0) -> AssignmentReport | None:
        """Commit the assignment for the current released set; None without epoch 0 or
        while a candidate's results are missing (`replan_missing`).

        `resolving`: the epoch's append plan is the fallback. It is committed at once by
        a UAV it releases; else the plan solved again from every survivor's standing
        for it is committed, once they are all in (`resolve_ready`), or the fallback
        itself STANDINGS_WAIT_S after `now` (`expire`); None meanwhile, and when it
        changes nothing for this UAV."""
        fallback = self._fallback()
        if fallback is None:
            return None
        if not self.resolving or self.own_id in fallback.released:
            self.awaiting = None
            return self._commit(fallback)
        committed = self.committed
        if committed is not None and fallback.digest in (committed.digest, committed.basis):
            self.awaiting = None
            return None  # this epoch's plan is followed already
        if self.awaiting is None or self.awaiting.digest != fallback.digest:
            self.awaiting, self.awaiting_since = fallback, now
        return self.resolve_ready()

    def _commit(self, report: AssignmentReport) -> AssignmentReport:
        self.committed = report
        self._update_reached()
        return report

    def _fallback(self) -> AssignmentReport | None:
        """The append plan for the current released set (`fleet.consensus.replan`)."""
        if self.base is None or self.replan_missing():
            return None
        current = self.current
        plan = replan(
            self.base,
            self._times(),
            self.released,
            self.air_legs(self.base.team),
            removed=current.removed,
            added=added_targets(current),
            finished=self.finished(),
        )
        heads = plan.pairs
        membership = self.membership
        epoch, digest = plan.epoch, plan.digest
        if membership.back or membership.asked:
            # Somebody came back, or asked for a re-plan in changed air: the counts, not
            # the set, name the epoch.
            epoch = membership.epoch
            digest = membership_digest(
                self.base.digest, membership.left, membership.back, membership.asked
            )
            digest = finished_digest(digest, plan.finished)
        # Each revision of the mission is one epoch more (fleet.consensus.mission_change).
        epoch += current.revision
        digest = change_digest(digest, current)
        return self._report(
            target=heads.get(self.own_id),
            pairs=heads,
            queues={uav: q for uav, q in plan.plan.queues.items() if q},
            arrivals={uav: a for uav, a in plan.plan.arrivals.items() if a},
            unserved=plan.unserved,
            team=self.base.team,
            digest=digest,
            epoch=epoch,
            released=plan.released,
            # Counts only once somebody came back (or asked): until then each is 1, and
            # `released` says the same (fleet.consensus.membership.report_counts).
            left=dict(sorted(membership.left.items()))
            if membership.back or membership.asked
            else {},
            back=dict(sorted(membership.back.items())),
            asked=dict(sorted(membership.asked.items())),
            revision=current.revision,
        )

    # ---- solving what is left (fleet.consensus.resolve) --------------------------------
    def add_standing(self, result: UavResult) -> bool:
        """Keep a survivor's standing (the first of each UAV for each basis); False if it
        is not one for this mission."""
        basis = result.basis
        if basis is None or result.mission != self.mission or result.uav not in self.team:
            return False
        held = self.standings.get(basis)
        if held is None:
            held = self.standings[basis] = {}
            while len(self.standings) > STANDING_BASES:
                del self.standings[next(iter(self.standings))]
        if result.uav in held:
            return False
        held[result.uav] = result
        return True

    def stands_for(self) -> AssignmentReport | None:
        """The append plan whose survivors' standings this UAV waits for or could still
        use: the one awaited, else the one committed (not resolved), if it is a re-plan."""
        if self.awaiting is not None:
            return self.awaiting
        committed = self.committed
        if committed is not None and committed.epoch > 0 and committed.basis is None:
            return committed
        return None

    def fallback_moved(self) -> bool:
        """The append plan awaited or followed (`stands_for`) is no longer the one the
        current input gives: a UAV finished its queue since (`finished`)."""
        held = self.stands_for()
        if held is None:
            return False
        fallback = self._fallback()
        return fallback is not None and fallback.digest != held.digest

    @staticmethod
    def survivors(fallback: AssignmentReport) -> tuple[int, ...]:
        """The UAVs taking part in a re-plan: its team, less the released, and the UAVs
        outside its team counted in since (`rejoin`: counted back, not out again). Those
        hold nothing in the append plan (it is epoch 0's, whose times they lack); they
        take part in the plan solved again from the standings."""
        left, back = report_counts(fallback.released, fallback.left, fallback.back)
        gone = set(fallback.released)
        return tuple(
            sorted(
                uav
                for uav in set(fallback.team) | back.keys()
                if uav not in gone and left.get(uav, 0) <= back.get(uav, 0)
            )
        )

    def missing_standings(self) -> tuple[int, ...]:
        """Survivors whose standing for the plan `stands_for` this UAV lacks."""
        fallback = self.stands_for()
        if fallback is None:
            return ()
        held = self.standings.get(fallback.digest, {})
        return tuple(uav for uav in self.survivors(fallback) if uav not in held)

    def standing_of(self, uav: int, basis: str | None = None) -> UavResult | None:
        """`uav`'s standing for append plan `basis`, if held; with no basis, for the one
        this UAV awaits or follows (`stands_for`): the standing still of use."""
        if basis is None:
            fallback = self.stands_for()
            if fallback is None:
                return None
            basis = fallback.digest
        return self.standings.get(basis, {}).get(uav)

    def standings_to_fetch(self, now: float) -> tuple[str, tuple[int, ...]] | None:
        """The awaited append plan's digest and the survivors whose standings for it are
        still missing FETCH_INTERVAL into the wait (a lost put, or one made before this
        UAV listened): asked for by query once per plan; None otherwise."""
        fallback, since = self.awaiting, self.awaiting_since
        if fallback is None or since is None or now - since < FETCH_INTERVAL:
            return None
        if fallback.digest in self.standings_asked:
            return None
        self.standings_asked.add(fallback.digest)
        missing = tuple(u for u in self.missing_standings() if u != self.own_id)
        return (fallback.digest, missing) if missing else None

    def resolve_ready(self) -> AssignmentReport | None:
        """Commit the plan solved again from the survivors' standings, once every one
        is in for the append plan `stands_for`; None before, or if not a re-plan."""
        fallback = self.stands_for()
        if not self.resolving or fallback is None or self.missing_standings():
            return None
        held = self.standings[fallback.digest]
        current = self.current
        count = len(current.targets)
        taking_part = {uav: held[uav] for uav in self.survivors(fallback)}
        if any(len(r.times) != count for r in taking_part.values()):
            return None  # of another revision: the fallback stands
        standings = {
            uav: Standing(r.times, r.flying, frozenset(r.reached)) for uav, r in taking_part.items()
        }
        objective = self.targets.objective
        left = remaining_targets(count, current.removed, standings)
        air = {uav: Air.of(r) for uav, r in taking_part.items()}
        legs = AirLegs(self.geometry, air, self.legs)
        solved = resolve(standings, left, legs, objective).plan
        heads = solved.heads()
        self.awaiting = None
        return self._commit(
            self._report(
                target=heads.get(self.own_id),
                pairs=heads,
                queues={uav: q for uav, q in solved.queues.items() if q},
                arrivals={uav: a for uav, a in solved.arrivals.items() if a},
                unserved={t: NO_TAKER for t in solved.unassigned},
                team=fallback.team,
                digest=resolve_digest(fallback.digest, standings, left, objective),
                epoch=fallback.epoch,
                released=fallback.released,
                left=dict(fallback.left),
                back=dict(fallback.back),
                asked=dict(fallback.asked),
                revision=fallback.revision,
                basis=fallback.digest,
            )
        )

    def expire(self, now: float) -> AssignmentReport | None:
        """Commit the awaited append plan once STANDINGS_WAIT_S passed without every
        survivor's standing (None before): nothing waits longer for a missing one."""
        fallback, since = self.awaiting, self.awaiting_since
        if fallback is None or (since is not None and now - since < STANDINGS_WAIT_S):
            return None
        self.awaiting = None
        return self._commit(fallback)

    def adopt_resolved(self, report: AssignmentReport) -> AssignmentReport | None:
        """Take a teammate's resolved plan of the append plan this UAV awaits or
        follows (it holds every standing this UAV may lack); None if it is not one."""
        fallback = self.stands_for()
        if report.basis is None or fallback is None or report.basis != fallback.digest:
            return None
        if report.mission != self.mission or report.revision != fallback.revision:
            return None
        self.awaiting = None
        return self._own_copy(report)

    def _times(self) -> dict[int, tuple[float | None, ...]]:
        """The epoch-0 times, and each UAV's estimate to every target added in flight."""
        current = self.current
        extra = range(planned_count(current), len(current.targets))
        if not extra:
            return {uav: result.times for uav, result in self.results.items()}
        return {
            uav: result.times + estimated_times(result, current.targets, extra)
            for uav, result in self.results.items()
        }


def _counts(report: AssignmentReport) -> tuple[dict[int, int], dict[int, int], dict[int, int]]:
    """A report's membership counts: left, back (`report_counts`) and asked, of its
    author only (`own_asked`: another UAV's ask is believed from that UAV's word)."""
    left, back = report_counts(report.released, report.left, report.back)
    return left, back, own_asked(report.uav, report.asked)
