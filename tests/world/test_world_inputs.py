"""The robots' inputs as the physics side keeps them across a change of layout (pure)."""

import math

import numpy as np

from fleet.world.inputs import RobotInputs


def test_a_new_layout_keeps_each_robots_inputs_by_name():
    old = RobotInputs.empty(1, 3)
    old.commands[:] = [(0.1, 0.0, 5.0, 1.0), (0.2, 0.0, 6.0, 2.0), (0.3, 0.0, 7.0, 3.0)]
    old.battery[:] = [10.0, 20.0, 30.0]
    old.odom_subscribers[:] = [1, 2, 3]
    new = old.remapped(["a", "b", "c"], ["c", "new", "a"], generation=2)
    assert new.generation == 2
    assert new.commands[:, 0].tolist() == [0.3, 0.0, 0.1]
    assert new.battery_of(0) == 30.0 and new.battery_of(1) is None and new.battery_of(2) == 10.0
    assert new.link(1) == {"cmd_age": None, "odom_subscribers": 0}  # "new" has had nothing yet
    assert new.odom_subscribers.tolist() == [3, 0, 1]
    assert math.isinf(new.commands[1, 2])


def test_inputs_of_another_layout_are_not_mixed_in():
    """A snapshot whose rows do not match the names it is said to be of gives nothing."""
    stale = RobotInputs.empty(1, 2)
    stale.battery[:] = [50.0, 60.0]
    fresh = stale.remapped(["a", "b", "c"], ["a"], generation=3)
    assert len(fresh) == 1 and np.isnan(fresh.battery[0])


def test_a_battery_reading_goes_stale_once_its_node_is_gone():
    """A robot whose battery node was removed (`enable_battery: false`) shows no battery once its
    last reading is older than BATTERY_STALE, instead of that reading forever."""
    from fleet.world.inputs import BATTERY_STALE, NEVER, fresh_battery

    now = 1000.0
    readings = [(50.0, now - 1.0), (80.0, now - BATTERY_STALE - 0.5), (float("nan"), NEVER), (20.0, now)]
    got = fresh_battery(readings, now)
    assert got[0] == 50.0 and got[3] == 20.0
    assert np.isnan(got[1]) and np.isnan(got[2])
    assert fresh_battery([], now).shape == (0,)
