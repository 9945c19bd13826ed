"""Large DDS receive buffers for the one participant that takes every robot's topics: a bridge.

Each step the world publishes every robot's odometry and scans at once.  A bridge exporting
them takes the whole burst in one participant, and with the system's default socket receive
buffer (212 KiB on Linux) the burst of 100 robots (about 220 KiB) overflowed it: the kernel
dropped 5% of the best-effort scans before Fast DDS saw them (bench/results/dataplane.md).
A Fast DDS XML profile (the only way to size these sockets through rmw_fastrtps) asks for
RECEIVE_BUFFER_BYTES; Linux grants at most net.core.rmem_max.
"""

from __future__ import annotations

import os
from pathlib import Path

RECEIVE_BUFFER_BYTES = 4 * 1024 * 1024  # a burst of 1,000 robots' scans
PROFILES_VARIABLE = "FASTRTPS_DEFAULT_PROFILES_FILE"  # read by Fast DDS 2.x, Jazzy's
RMEM_MAX = Path("/proc/sys/net/core/rmem_max")


def profile(receive_buffer_bytes: int = RECEIVE_BUFFER_BYTES) -> str:
    """A Fast DDS profile, the default for the process's participants, with that buffer."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<!-- Written by fleet's zenoh bridge: see fleet/dataplane/receive_buffers.py -->
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <participant profile_name="fleet_bridge" is_default_profile="true">
      <rtps>
        <listenSocketBufferSize>{receive_buffer_bytes}</listenSocketBufferSize>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def use_large_receive_buffers(profile_path: Path) -> str | None:
    """Make this process's DDS participants ask for large receive buffers (before rclpy.init),
    writing their profile to `profile_path`.  Returns a warning for the log when they will not get them, else None."""
    if os.environ.get(PROFILES_VARIABLE):
        return (
            f"{PROFILES_VARIABLE} is set ({os.environ[PROFILES_VARIABLE]}): that profile decides the DDS "
            f"receive buffers; bursts of many robots' best-effort topics may be lost below "
            f"{RECEIVE_BUFFER_BYTES} bytes (listenSocketBufferSize)"
        )
    profile_path.write_text(profile())
    os.environ[PROFILES_VARIABLE] = str(profile_path)
    try:
        granted = int(RMEM_MAX.read_text())
    except (OSError, ValueError):
        return None  # not Linux, or not readable: nothing to say
    if granted < RECEIVE_BUFFER_BYTES:
        return (
            f"net.core.rmem_max is {granted} bytes: DDS receive buffers stop there, and bursts of many "
            f"robots' best-effort topics may be lost (raise it: sysctl -w net.core.rmem_max={RECEIVE_BUFFER_BYTES})"
        )
    return None
