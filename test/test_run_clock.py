"""gnss-sim run's realtime /clock: between two epochs it steps onto the trajectory player's ticks, thinned to at
most one per REALTIME_CLOCK_PERIOD_S, and ends on the epoch (commands/run/clock.realtime_clock_steps_s)."""
import numpy as np
import pytest

from gnss_sim_ros2.commands.run.clock import REALTIME_CLOCK_PERIOD_S, realtime_clock_steps_s


@pytest.mark.parametrize("t_from_s,t_to_s,tick_s", [
    (0.0, 0.1, 0.05),        # the default: 10 Hz epochs, a 20 Hz player
    (0.1, 0.2, 0.05),
    (0.3, 0.4, 0.03),        # ticks not on the epoch grid
    (0.0, 1.0, 0.1),         # 1 Hz epochs, a 10 Hz player
    (0.0, 0.1, 0.001),       # a 1 kHz player: thinned
    (5.0, 5.1, 0.2),         # no tick between the epochs
    (1e6, 1e6 + 0.1, 0.05),  # far into a long run
])
def test_steps_land_on_ticks_between_the_epochs_and_end_on_the_epoch(t_from_s, t_to_s, tick_s):
    steps = realtime_clock_steps_s(t_from_s, t_to_s, tick_s)
    assert steps[-1] == t_to_s
    inner = np.array(steps[:-1])
    assert np.all(inner > t_from_s) and np.all(inner < t_to_s)
    assert np.all(np.diff(steps) > 0)
    # every step is a tick of the player (to the float's rounding of a multiple)
    k = inner / tick_s
    assert np.allclose(k, np.round(k), atol=1e-6)
    if len(inner) > 1:
        assert np.min(np.diff(inner)) >= REALTIME_CLOCK_PERIOD_S - 1e-9
    # no tick at or beyond the thinning step is skipped
    step_s = max(tick_s, REALTIME_CLOCK_PERIOD_S)
    expected = len([j for j in range(int(t_from_s / step_s) - 2, int(t_to_s / step_s) + 3)
                    if t_from_s + 1e-9 < j * np.ceil(step_s / tick_s - 1e-9) * tick_s < t_to_s - 1e-9])
    assert len(inner) == expected


def test_the_default_player_gets_one_clock_step_between_10_hz_epochs():
    # before: a /clock every 10 ms of wall time (nine between two 10 Hz epochs); the player's one tick is enough
    assert realtime_clock_steps_s(0.2, 0.3, 1 / 20.0) == pytest.approx([0.25, 0.3])
