"""The environment a user's shell gives a command, for the benchmarks that time commands as users
run them.

The ROS wheels' bootstrapper (a .pth file) starts every Python of this venv a second time, with
LD_LIBRARY_PATH set, unless its guard variable says that was done; a benchmark started from such
a Python inherits the guard, so the commands it times would skip that second start, which every
command typed in a shell pays (`python -c pass` 0.077 s against 0.041 s without it, 27 Nov,
medians of 15 pairs).
"""

from __future__ import annotations

import os

ROS_WHEELS_GUARD = "_ROS_WHEELS_BOOTSTRAP_COMPLETE"


def user_env(env: dict[str, str] | None = None) -> dict[str, str]:
    """`env` (default: this process's) as a user's shell has it: without the bootstrapper's guard."""
    source = os.environ if env is None else env
    return {key: value for key, value in source.items() if key != ROS_WHEELS_GUARD}
