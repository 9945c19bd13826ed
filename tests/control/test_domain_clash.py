"""Pure tests of the one-domain-per-fleet rule a deploy checks before it sends anything."""

from __future__ import annotations

from types import SimpleNamespace

from fleet.plan import FleetView, domain_clash


def fleet(name: str, domain_id: int):
    return SimpleNamespace(fleet=name, domain_id=domain_id)


def test_another_fleet_in_the_domain_is_named_with_a_free_one():
    view = FleetView(agents=[], robots=[], domain_ids={"two_robots": 42, "lab": 43})
    assert domain_clash(fleet("other", 42), view) == (
        "ros.domain_id 42 is fleet two_robots's on this router: each fleet needs a ROS domain of its own, "
        "or their nodes meet (domains in use: 42, 43; 44 is free)"
    )


def test_the_fleet_itself_and_other_domains_are_fine():
    view = FleetView(agents=[], robots=[], domain_ids={"two_robots": 42})
    assert domain_clash(fleet("two_robots", 42), view) is None
    assert domain_clash(fleet("other", 7), view) is None
    assert domain_clash(fleet("other", 0), FleetView(agents=[], robots=[])) is None


def test_the_domain_offered_is_never_the_default_one():
    view = FleetView(agents=[], robots=[], domain_ids={"a": 232, "b": 1})
    clash = domain_clash(fleet("c", 232), view)
    assert clash is not None and clash.endswith("(domains in use: 1, 232; 2 is free)")
