"""The real-time control loop of the real-robot envs, as RealROS runs it.

``environment_loop_rate`` (Hz) is the loop's rate: at most one env step per period.
``action_cycle_time`` (s) is how long a step waits between acting and observing (0: one loop
period). A step acts at ``t``, then observes at ``max(t + cycle, previous observation + period)``:
with a fast agent the steps come exactly at the loop rate, without drift; a slow agent gets one
step per ``cycle`` after each action.

While it waits, :meth:`ControlLoop.wait` checks a watchdog every ``tick`` seconds, so a robot that
disappears is noticed within ``tick`` plus the state timeout, not at the end of a long cycle.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class ControlLoop:
    """Pacing of act -> wait -> observe.

    Args:
        environment_loop_rate: loop rate in Hz (> 0).
        action_cycle_time: seconds from acting to observing; 0 means one loop period. A value
            shorter than one period is refused (as RealROS does): raise the rate instead.
        tick: largest sleep between watchdog checks.
    """

    def __init__(self, environment_loop_rate: float = 10.0, action_cycle_time: float = 0.0, *,
                 tick: float = 0.01) -> None:
        rate = float(environment_loop_rate)
        cycle = float(action_cycle_time)
        if not rate > 0 or rate > 1000:
            raise ValueError(f"environment_loop_rate must be in (0, 1000] Hz, got {environment_loop_rate!r}")
        if not cycle >= 0 or cycle > 60:
            raise ValueError(f"action_cycle_time must be in [0, 60] s, got {action_cycle_time!r}")
        self.period = 1.0 / rate
        if 0 < cycle < self.period - 1e-9:
            raise ValueError(
                f"action_cycle_time {cycle:g} s is shorter than one loop period (1 / environment_loop_rate = "
                f"{self.period:g} s): raise environment_loop_rate to at least {1.0 / cycle:g} Hz or set "
                "action_cycle_time to 0 (one period)"
            )
        self.rate = rate
        self.cycle = cycle if cycle > 0 else self.period
        self.tick = float(tick)
        self.last_observe: float | None = None
        self.last_act: float | None = None

    def start_episode(self) -> None:
        """Forget the previous step's timing (the first step after a reset is not paced against it)."""
        self.last_observe = None
        self.last_act = None

    def observe_time(self, acted_at: float) -> float:
        """When the step that acted at ``acted_at`` observes (monotonic seconds)."""
        at = acted_at + self.cycle
        if self.last_observe is not None:
            at = max(at, self.last_observe + self.period)
        return at

    def wait(self, acted_at: float, watchdog: Callable[[], None] | None = None) -> float:
        """Sleep until the observation time, calling ``watchdog()`` (which raises to abort) each tick.

        Returns the observation time (monotonic seconds).
        """
        self.last_act = acted_at
        deadline = self.observe_time(acted_at)
        while True:
            if watchdog is not None:
                watchdog()
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            time.sleep(min(remaining, self.tick))
        self.last_observe = time.monotonic()
        return self.last_observe
