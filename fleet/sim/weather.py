"""Weather worth planning for: a mean wind that drifts, gusts, and the autopilot's
lagging, erring estimate of it. Pure and reproducible (a seed, no clock).

Per scenario (`WeatherSpec`, the `[wind]` table of docs/simulator.md):

* the **mean wind** drifts slowly in speed and direction: each is the scenario's value
  plus a sine of amplitude `drift_speed` (m/s) or `drift_direction` (degrees) over
  `drift_period` seconds (the direction's period 1.37 times longer, so the two never
  move in step), with phases drawn from `seed`. The whole sky drifts alike: every
  aircraft of a scenario shares the drift;
* **gusts** are each aircraft's own: per component a first-order Gauss-Markov process
  (the simplest model with the right shape: correlated over `gust_time` seconds, of
  standard deviation `gust`), drawn from `seed` and the Piccolo ID;
* the **estimate** the autopilot reports in its telemetry (`wind_south`, `wind_west`)
  follows the true wind through a first-order lag of `estimate_lag` seconds (a real
  estimator needs turns to observe the wind) and is off by a constant bias per
  component, drawn once per aircraft with standard deviation `estimate_error` (m/s).
  It starts converged on the wind at time 0.

The same scenario and seed give the same weather, step for step. With no drift, gusts
or estimate error (the default) the wind is the constant mean and a step costs nothing.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

from fleet.sim.aircraft import Wind

__all__ = ["DIRECTION_PERIOD_RATIO", "Weather", "WeatherSpec"]

#: The direction's drift period over the speed's: irrational-ish, so they never lock.
DIRECTION_PERIOD_RATIO = 1.37


@dataclass(frozen=True, slots=True)
class WeatherSpec:
    """A scenario's weather; the defaults are a steady `mean` wind, exactly reported."""

    mean: Wind = field(default_factory=Wind)
    drift_speed: float = 0.0  #: m/s, amplitude of the mean speed's slow change
    drift_direction_deg: float = 0.0  #: degrees, amplitude of the direction's
    drift_period_s: float = 1800.0  #: seconds, the speed's drift period
    gust: float = 0.0  #: m/s, standard deviation of each gust component
    gust_time_s: float = 5.0  #: seconds, how long a gust lasts (its correlation time)
    estimate_lag_s: float = 10.0  #: seconds, the reported estimate's lag
    estimate_error: float = 0.0  #: m/s, standard deviation of the estimate's bias
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("drift_speed", "drift_direction_deg", "gust", "estimate_error"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a number >= 0, got {value}")
        for name in ("drift_period_s", "gust_time_s", "estimate_lag_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a positive number, got {value}")

    @property
    def steady(self) -> bool:
        """True when the wind never changes and is reported exactly."""
        return self.drift_speed == 0.0 and self.drift_direction_deg == 0.0 and self.gust == 0.0

    @property
    def strongest(self) -> float:
        """The fastest the wind plausibly blows (m/s): mean, drift and three sigma of gust."""
        return self.mean.speed + self.drift_speed + 3.0 * self.gust


def _phases(seed: int) -> tuple[float, float]:
    rng = random.Random(f"weather-drift:{seed}")
    return rng.uniform(0.0, math.tau), rng.uniform(0.0, math.tau)


class Weather:
    """The weather one aircraft flies in; `advance` it by every simulation step."""

    def __init__(self, spec: WeatherSpec, piccolo_id: int = 0) -> None:
        self.spec = spec
        self.time_s = 0.0
        self._speed_phase, self._direction_phase = _phases(spec.seed)
        self._rng = random.Random(f"weather-gust:{spec.seed}:{piccolo_id}")
        self._bias = (
            (self._rng.gauss(0.0, spec.estimate_error), self._rng.gauss(0.0, spec.estimate_error))
            if spec.estimate_error > 0.0
            else (0.0, 0.0)
        )
        self._gust = (0.0, 0.0)
        self.wind = self.mean_at(0.0)
        self._estimate = self.wind

    def mean_at(self, t: float) -> Wind:
        """The mean wind at `t` seconds (the drift alone: no gust, no estimate's lag or
        bias); the same for every aircraft of the scenario."""
        spec = self.spec
        if spec.drift_speed == 0.0 and spec.drift_direction_deg == 0.0:
            return spec.mean
        speed = spec.mean.speed + spec.drift_speed * math.sin(
            math.tau * t / spec.drift_period_s + self._speed_phase
        )
        # Direction the air moves to, clockwise from north.
        direction = math.atan2(spec.mean.east, spec.mean.north) + math.radians(
            spec.drift_direction_deg
        ) * math.sin(
            math.tau * t / (DIRECTION_PERIOD_RATIO * spec.drift_period_s) + self._direction_phase
        )
        speed = max(speed, 0.0)
        return Wind(north=speed * math.cos(direction), east=speed * math.sin(direction))

    def advance(self, dt: float) -> Wind:
        """Move the weather on by `dt` seconds; the true wind now."""
        spec = self.spec
        self.time_s += dt
        if spec.steady:
            return self.wind
        mean = self.mean_at(self.time_s)
        if spec.gust > 0.0:
            # Exact discretisation of the Gauss-Markov process, whatever dt.
            keep = math.exp(-dt / spec.gust_time_s)
            spread = spec.gust * math.sqrt(1.0 - keep * keep)
            self._gust = (
                keep * self._gust[0] + spread * self._rng.gauss(0.0, 1.0),
                keep * self._gust[1] + spread * self._rng.gauss(0.0, 1.0),
            )
        self.wind = Wind(north=mean.north + self._gust[0], east=mean.east + self._gust[1])
        follow = 1.0 - math.exp(-dt / spec.estimate_lag_s)
        self._estimate = Wind(
            north=self._estimate.north + follow * (self.wind.north - self._estimate.north),
            east=self._estimate.east + follow * (self.wind.east - self._estimate.east),
        )
        return self.wind

    @property
    def estimate(self) -> Wind:
        """The wind the autopilot reports: lagging and biased (module docstring)."""
        if not self._bias[0] and not self._bias[1]:
            return self._estimate
        return Wind(
            north=self._estimate.north + self._bias[0], east=self._estimate.east + self._bias[1]
        )
