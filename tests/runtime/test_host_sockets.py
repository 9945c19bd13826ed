"""A host pool's socket directory (in the system's temporary directory: socket paths are short)
is removed by the pool's stop, and, when its agent was killed before it could stop, by the next
agent on the same state directory or by fleet.testing's teardown: none is left in /tmp."""

from __future__ import annotations

import os
from pathlib import Path

from fleet.rules import hosts_dir, hosts_root
from fleet.runtime.hosting import SOCKET_DIR_LINK, HostPool, remove_orphaned_socket_dirs


def test_a_stopped_pool_leaves_no_socket_directory(tmp_path):
    pool = HostPool(hosts_dir(tmp_path, "f", 1), {}, group_size=2)
    sockets = pool.socket_dir
    assert sockets.is_dir() and (pool.directory / SOCKET_DIR_LINK).resolve() == sockets.resolve()
    pool.stop()
    assert not sockets.exists() and not (pool.directory / SOCKET_DIR_LINK).is_symlink()


def test_the_socket_directories_of_a_killed_agent_s_pools_are_found_and_removed(tmp_path):
    pools = [HostPool(hosts_dir(tmp_path, fleet, n), {}, group_size=2) for n, fleet in enumerate("ab", 1)]
    left = [pool.socket_dir for pool in pools]  # the agent is killed: no stop runs
    assert all(path.is_dir() for path in left)
    remove_orphaned_socket_dirs(hosts_root(tmp_path))
    assert not any(path.exists() for path in left)
    assert not list(hosts_root(tmp_path).glob(f"*/{SOCKET_DIR_LINK}"))


def test_only_fleet_s_own_socket_directories_are_removed(tmp_path):
    """A link someone pointed elsewhere removes nothing but itself."""
    precious = tmp_path / "precious"
    precious.mkdir()
    directory = hosts_dir(tmp_path, "f", 1)
    directory.mkdir(parents=True)
    (directory / SOCKET_DIR_LINK).symlink_to(precious)
    remove_orphaned_socket_dirs(hosts_root(tmp_path))
    assert precious.is_dir() and not os.path.lexists(directory / SOCKET_DIR_LINK)
    assert Path(hosts_root(tmp_path)).is_dir()
