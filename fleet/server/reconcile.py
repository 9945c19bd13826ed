"""What an apply changes: pure comparison of bundles by content hash."""

from __future__ import annotations

from fleet.wire.protocol import BundleMessage, Changes


def plan_changes(
    current: dict[str, BundleMessage],
    desired: dict[str, BundleMessage],
    again: set[str] | frozenset[str] = frozenset(),
) -> Changes:
    """Robots to start, stop, restart, hot-update, or leave alone.

    `current` is what the units run (or are being brought to); `again` are units to start again
    even when their bundle is unchanged: their start failed, or their ROS environment changed.
    """
    changes = Changes()
    for name in sorted(desired):
        bundle = desired[name]
        running = current.get(name)
        if running is None:
            changes.start.append(name)
        elif running.digest != bundle.digest or name in again:
            changes.restart.append(name)
        elif running.hot_digest != bundle.hot_digest:
            changes.hot_update.append(name)
        else:
            changes.unchanged.append(name)
    changes.stop = sorted(set(current) - set(desired))
    return changes
