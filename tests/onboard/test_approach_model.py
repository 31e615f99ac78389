"""Tests of the approach-time model (onboard.planner.approach_model)."""

from __future__ import annotations

import itertools
import math
import random
import subprocess
import sys
import time

import pytest

from fleet.geo.aircraft import AircraftLimits, turn_radius
from fleet.geo.wind import Wind
from fleet.sim.aircraft import AircraftState
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.guidance import fly_to_point
from onboard.planner.approach_model import (
    PLANNABLE_WIND_SHARE,
    ApproachTimeModel,
    LpBackend,
    TargetStatus,
    default_steps,
)
from tests.support.pure_pursuit import fly_pure_pursuit

LIMITS = AircraftLimits()
V = LIMITS.max_airspeed
R = turn_radius(V, LIMITS.bank_limit_deg)


@pytest.fixture(scope="module")
def model() -> ApproachTimeModel:
    return ApproachTimeModel(LIMITS)


def polar(dist: float, bearing_deg: float) -> tuple[float, float]:
    b = math.radians(bearing_deg)
    return dist * math.cos(b), dist * math.sin(b)


# -- approach-time model ---------------------------------------------------------------


def test_straight_ahead_at_max_speed_is_distance_over_speed(model: ApproachTimeModel) -> None:
    for d in (150.0, 1000.0, 4000.0):
        (t,) = model.solve((0.0, 0.0), (V, 0.0), [(d, 0.0)])
        assert t is not None
        # The speed 16-gon is scaled to the circle's mean radius: 1.3 % fast dead ahead.
        assert t == pytest.approx(d / V, rel=0.015)


def test_heading_and_position_are_respected(model: ApproachTimeModel) -> None:
    # Flying north from (500, -200): a target 2 km north is straight ahead.
    (t,) = model.solve((500.0, -200.0), (0.0, V), [(500.0, 1800.0)])
    assert t == pytest.approx(2000.0 / V, rel=0.015)


def test_target_behind_takes_longer_than_ahead(model: ApproachTimeModel) -> None:
    ahead, behind, abeam = model.solve(
        (0.0, 0.0), (V, 0.0), [(1500.0, 0.0), (-1500.0, 0.0), (0.0, 1500.0)]
    )
    assert ahead is not None and behind is not None and abeam is not None
    assert ahead < abeam < behind
    # Turning round takes about half a turn circle's circumference.
    assert behind - ahead > 0.8 * math.pi * R / V


def test_left_and_right_are_symmetric(model: ApproachTimeModel) -> None:
    left, right = model.solve((0.0, 0.0), (V, 0.0), [(-800.0, 900.0), (-800.0, -900.0)])
    assert left == pytest.approx(right, rel=1e-6)


@pytest.mark.parametrize("bearing", [0.0, 45.0, 135.0, 180.0])
def test_times_are_monotone_in_distance(model: ApproachTimeModel, bearing: float) -> None:
    targets = [polar(d, bearing) for d in (600.0, 1000.0, 1500.0, 2500.0, 4000.0, 8000.0)]
    times = [t for t in model.solve((0.0, 0.0), (V, 0.0), targets) if t is not None]
    assert len(times) == len(targets)
    assert all(a < b for a, b in itertools.pairwise(times))


def test_reused_model_matches_fresh_model(model: ApproachTimeModel) -> None:
    targets = [polar(1200.0, 30.0), polar(2500.0, 200.0), polar(800.0, 110.0), (10.0, 5.0)]
    states = [
        ((0.0, 0.0), (V, 0.0)),
        ((300.0, -50.0), (-12.0, 20.0)),
        ((-1000.0, 700.0), (0.0, -25.0)),
    ]
    for position, velocity in states:
        reused = model.solve(position, velocity, targets)
        fresh = ApproachTimeModel(LIMITS).solve(position, velocity, targets)
        assert reused == pytest.approx(fresh, rel=1e-6, abs=1e-6)


def test_lp_scan_finds_the_first_feasible_node(model: ApproachTimeModel) -> None:
    """The scan's node is the arrival-step MILP optimum: every earlier node is refuted."""
    target = polar(1800.0, 150.0)
    (sol,) = model.solve_detailed((0.0, 0.0), (V, 0.0), [target])
    assert sol.status is TargetStatus.SOLVED and sol.node is not None
    assert sol.lp_time is not None
    assert model.node_times[sol.node - 1] < sol.lp_time <= model.node_times[sol.node]
    # Exhaustive check through the model's own LP (private, on purpose).
    model._set_target(target[0], abs(target[1]), (0.0, 0.0))
    gaps = [model._gap_at(k) for k in range(sol.node + 1)]
    assert all(g is not None and g > 1e-2 for g in gaps[:-1])
    assert gaps[-1] is not None and gaps[-1] <= 1e-2


def test_turn_bound_tracks_flown_time_on_all_bearings(model: ApproachTimeModel) -> None:
    targets = [polar(2000.0, b) for b in range(0, 360, 30)]
    # The LP's own estimate: the reported time is also capped by the Dubins time, which
    # is this reference's time by construction.
    predicted = [s.lp_time for s in model.solve_detailed((0.0, 0.0), (V, 0.0), targets)]
    for target, t in zip(targets, predicted, strict=True):
        flown = fly_pure_pursuit((0.0, 0.0), (V, 0.0), target, LIMITS)
        assert t is not None and flown is not None
        assert t == pytest.approx(flown, rel=0.05), target


def test_turn_bound_beats_pure_point_mass_behind() -> None:
    target = (-1000.0, 0.0)
    flown = fly_pure_pursuit((0.0, 0.0), (V, 0.0), target, LIMITS)
    pure_model = ApproachTimeModel(LIMITS, turn_constraint=False)
    (pure_sol,) = pure_model.solve_detailed((0.0, 0.0), (V, 0.0), [target])
    (turn_sol,) = ApproachTimeModel(LIMITS).solve_detailed((0.0, 0.0), (V, 0.0), [target])
    pure, turn = pure_sol.lp_time, turn_sol.lp_time
    assert flown is not None and pure is not None and turn is not None
    assert abs(turn - flown) < abs(pure - flown)


def test_target_passed_between_nodes_is_capped_by_dubins(model: ApproachTimeModel) -> None:
    # 3 m dead ahead: the aircraft is there in 0.1 s, but the LP can only place the
    # arrival on a node (2 s), where the point mass cannot be without turning round.
    (sol,) = model.solve_detailed((0.0, 0.0), (V, 0.0), [(3.0, 0.0)])
    assert sol.lp_time is not None and sol.lp_time > 10.0
    assert sol.time == pytest.approx(3.0 / V)


def test_target_on_the_aircraft_takes_no_time(model: ApproachTimeModel) -> None:
    assert model.solve((5.0, 5.0), (V, 0.0), [(5.0, 5.0)]) == [0.0]


def test_unreachable_within_horizon_is_none() -> None:
    short = ApproachTimeModel(LIMITS, horizon_s=60.0)
    near, far = short.solve((0.0, 0.0), (V, 0.0), [(1000.0, 0.0), (5000.0, 0.0)])
    assert near is not None and far is None
    (sol,) = short.solve_detailed((0.0, 0.0), (V, 0.0), [(-1700.0, 0.0)])
    assert sol.status is TargetStatus.UNREACHABLE and sol.time is None


def test_passed_deadline_gives_none(model: ApproachTimeModel) -> None:
    past = time.monotonic() - 1.0
    out = model.solve_detailed((0.0, 0.0), (V, 0.0), [(1000.0, 0.0), (0.0, 2000.0)], past)
    assert [s.time for s in out] == [None, None]
    assert all(s.status is TargetStatus.DEADLINE for s in out)
    # The model still works afterwards.
    assert model.solve((0.0, 0.0), (V, 0.0), [(1000.0, 0.0)])[0] is not None


def test_speed_below_minimum_is_clamped(model: ApproachTimeModel) -> None:
    stopped, slow = model.solve((0.0, 0.0), (0.0, 0.0), [(1000.0, 0.0), (1000.0, 0.0)])
    assert stopped is not None and slow is not None
    (at_min,) = model.solve((0.0, 0.0), (LIMITS.min_airspeed, 0.0), [(1000.0, 0.0)])
    assert stopped == pytest.approx(at_min, rel=1e-6)


def test_rejects_non_finite_input(model: ApproachTimeModel) -> None:
    with pytest.raises(ValueError, match="must be finite"):
        model.solve((0.0, math.nan), (V, 0.0), [(1.0, 1.0)])
    with pytest.raises(ValueError, match="must be finite"):
        model.solve((0.0, 0.0), (V, 0.0), [(math.inf, 1.0)])


def test_default_steps_cover_the_horizon() -> None:
    for horizon in (7.0, 100.0, 600.0, 1000.0):
        steps = default_steps(horizon)
        assert sum(steps) == pytest.approx(horizon)
        assert all(s > 0.0 for s in steps)
    assert default_steps(600.0)[:10] == (2.0,) * 10
    with pytest.raises(ValueError, match="horizon must be positive"):
        default_steps(0.0)


# -- the onboard's LP on HiGHS against the Pyomo model ---------------------------------


def test_the_lp_on_highs_is_the_pyomo_models_lp() -> None:
    """Same columns, rows, order, bounds and coefficients as Pyomo hands to HiGHS."""
    ours = ApproachTimeModel(LIMITS, horizon_s=120.0)
    reference = ApproachTimeModel(LIMITS, horizon_s=120.0, backend=LpBackend.PYOMO)
    lps = []
    for model in (ours, reference):
        highs = model.lp.highs  # type: ignore[attr-defined]
        highs.ensureColwise()
        lps.append(highs.getLp())
    a, b = lps
    assert (a.num_col_, a.num_row_) == (b.num_col_, b.num_row_)
    for name in ("col_cost_", "col_lower_", "col_upper_", "row_lower_", "row_upper_"):
        assert list(getattr(a, name)) == list(getattr(b, name)), name
    for name in ("start_", "index_", "value_"):
        assert list(getattr(a.a_matrix_, name)) == list(getattr(b.a_matrix_, name)), name
    assert (a.sense_, a.offset_) == (b.sense_, b.offset_)


def test_the_lp_on_highs_gives_the_pyomo_models_times() -> None:
    """Random states and targets at 0.1-6 km: every solution is identical."""
    rng = random.Random(14)
    ours = ApproachTimeModel(AircraftLimits(max_airspeed=22.0))
    reference = ApproachTimeModel(AircraftLimits(max_airspeed=22.0), backend=LpBackend.PYOMO)
    for _ in range(12):
        position = (rng.uniform(-500.0, 500.0), rng.uniform(-500.0, 500.0))
        speed = rng.uniform(5.0, 30.0)
        heading = rng.uniform(0.0, math.tau)
        velocity = (speed * math.cos(heading), speed * math.sin(heading))
        targets = [polar(rng.uniform(100.0, 6000.0), rng.uniform(0.0, 360.0)) for _ in range(6)]
        got = ours.solve_detailed(position, velocity, targets)
        expected = reference.solve_detailed(position, velocity, targets)
        assert got == expected


@pytest.mark.e2e
def test_the_onboard_model_loads_neither_pyomo_nor_numpy() -> None:
    probe = (
        "import sys; from onboard.planner.approach_model import ApproachTimeModel;"
        "ApproachTimeModel().solve((0.0, 0.0), (30.0, 0.0), [(2000.0, 500.0)]);"
        "print(sorted(m.split('.')[0] for m in sys.modules"
        " if m.split('.')[0] in ('pyomo', 'numpy', 'highspy')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=60
    )
    assert set(out.stdout.split("'")[1::2]) == {"highspy"}


@pytest.mark.e2e
def test_highspy_imported_after_the_core_reuses_it() -> None:
    """Pyomo's `import highspy` after the onboard loaded the core alone (as in these tests)."""
    probe = (
        "from onboard.planner.approach_highs import load_highs_core; core = load_highs_core();"
        "import sys, highspy; assert sys.modules['highspy._core'] is core;"
        "print(highspy.Highs().version())"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip()


# -- in wind ---------------------------------------------------------------------------


def test_wind_straight_ahead_is_distance_over_ground_speed(model: ApproachTimeModel) -> None:
    # Ground velocity (V + 8, 0) in a tailwind of 8: airspeed V along +x.
    (tail,) = model.solve((0.0, 0.0), (V + 8.0, 0.0), [(3000.0, 0.0)], wind=Wind(8.0, 0.0))
    (head,) = model.solve((0.0, 0.0), (V - 8.0, 0.0), [(3000.0, 0.0)], wind=Wind(-8.0, 0.0))
    # The speed 16-gon's vertex dead ahead is 1.1 % fast in the air; a headwind makes
    # that a larger share of the ground speed (x V / (V - w)).
    assert tail == pytest.approx(3000.0 / (V + 8.0), rel=0.015)
    assert head == pytest.approx(3000.0 / (V - 8.0), rel=0.015 * V / (V - 8.0))


def test_wind_is_mirrored_with_the_target(model: ApproachTimeModel) -> None:
    wind = Wind(0.0, 6.0)  # blows to the left of an aircraft flying east
    left, right = model.solve(
        (0.0, 0.0), (V, 6.0), [(1500.0, 1500.0), (1500.0, -1500.0)], wind=wind
    )
    assert left is not None and right is not None
    assert left < right  # downwind is quicker
    (mirrored,) = model.solve((0.0, 0.0), (V, -6.0), [(1500.0, -1500.0)], wind=Wind(0.0, -6.0))
    assert mirrored == pytest.approx(left, rel=1e-6)


@pytest.mark.parametrize("bearing", range(0, 360, 30))
def test_wind_prediction_matches_the_simulators_flight(bearing: int) -> None:
    speed = 22.0
    model = ApproachTimeModel(AircraftLimits(max_airspeed=speed))
    target = (3000.0 * math.sin(math.radians(bearing)), 3000.0 * math.cos(math.radians(bearing)))
    # Heading north in a 10 m/s wind blowing east: a crosswind.
    state = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=speed)
    flown = fly_to_point(state, target, wind=SimWind(north=0.0, east=10.0), acceptance_radius=10.0)
    (predicted,) = model.solve((0.0, 0.0), (10.0, speed), [target], wind=Wind(10.0, 0.0))
    assert predicted == pytest.approx(flown, rel=0.03)


def test_wind_lp_on_highs_gives_the_pyomo_models_times() -> None:
    rng = random.Random(24)
    ours = ApproachTimeModel(AircraftLimits(max_airspeed=22.0))
    reference = ApproachTimeModel(AircraftLimits(max_airspeed=22.0), backend=LpBackend.PYOMO)
    for _ in range(6):
        heading = rng.uniform(0.0, math.tau)
        wind = Wind(rng.uniform(-12.0, 12.0), rng.uniform(-12.0, 12.0))
        velocity = (22.0 * math.cos(heading) + wind.east, 22.0 * math.sin(heading) + wind.north)
        targets = [polar(rng.uniform(300.0, 5000.0), rng.uniform(0.0, 360.0)) for _ in range(4)]
        got = ours.solve_detailed((0.0, 0.0), velocity, targets, wind=wind)
        expected = reference.solve_detailed((0.0, 0.0), velocity, targets, wind=wind)
        assert got == expected


def test_wind_faster_than_plannable_is_scaled_down(model: ApproachTimeModel) -> None:
    # Flying east at V through the air in a 50 m/s gale from the south-west: planned as
    # the same wind scaled down to PLANNABLE_WIND_SHARE of V, its direction kept.
    gale = Wind(30.0, 40.0)
    capped = Wind(30.0 * PLANNABLE_WIND_SHARE * V / 50.0, 40.0 * PLANNABLE_WIND_SHARE * V / 50.0)
    assert capped.speed == pytest.approx(PLANNABLE_WIND_SHARE * V)
    targets = [(-2000.0, -1500.0), (0.0, 3000.0), (2500.0, -500.0)]  # up-, down- and crosswind
    in_gale = model.solve((0.0, 0.0), (V + gale.east, gale.north), targets, wind=gale)
    in_capped = model.solve((0.0, 0.0), (V + capped.east, capped.north), targets, wind=capped)
    assert all(t is not None and math.isfinite(t) for t in in_gale)
    assert in_gale == pytest.approx(in_capped, rel=1e-9)
    # Any wind beyond the cap plans as the cap; a weaker one as itself.
    for share, beyond in ((0.9, True), (0.7, False)):
        other = Wind(gale.east * share * V / 50.0, gale.north * share * V / 50.0)
        times = model.solve((0.0, 0.0), (V + other.east, other.north), targets, wind=other)
        assert (times == pytest.approx(in_capped, rel=1e-9)) is beyond
    with pytest.raises(ValueError, match="finite"):
        model.solve((0.0, 0.0), (V, 0.0), [(1.0, 0.0)], wind=Wind(math.nan, 0.0))


@pytest.mark.parametrize("bearing", [30.0, 150.0, 210.0])
def test_wind_lp_scan_still_finds_the_first_feasible_node(
    model: ApproachTimeModel, bearing: float
) -> None:
    """The wind's jump bounds never skip a feasible node: every earlier node is refuted."""
    wind = Wind(-9.0, 5.0)  # a headwind from ahead-left of an aircraft flying east
    target = polar(2500.0, bearing)
    (sol,) = model.solve_detailed((0.0, 0.0), (V - 9.0, 5.0), [target], wind=wind)
    assert sol.status is TargetStatus.SOLVED and sol.node is not None
    # The scan's own frame: air velocity (V, 0) east, so the heading frame is the plane's;
    # a target on the right is mirrored, and the wind with it.
    side = 1.0 if target[1] >= 0.0 else -1.0
    model._set_target(target[0], abs(target[1]), (wind.east, side * wind.north))
    gaps = [model._gap_at(k) for k in range(sol.node + 1)]
    assert all(g is not None and g > 1e-2 for g in gaps[:-1])
    assert gaps[-1] is not None and gaps[-1] <= 1e-2
