"""`fleet_nodes/world`: the shared PyBullet world (see fleet.world).

world --config world.yaml [--status-file F] [--as-fast-as-possible] [--ros-args ...]
"""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    from fleet.world.cli import world_main

    return world_main(sys.argv[1:] if argv is None else argv)


if __name__ == "__main__":
    sys.exit(main())
