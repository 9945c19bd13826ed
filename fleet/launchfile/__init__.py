"""The one reader of YAML and XML launch files: `.launch.yaml` / `.launch.xml` text to a
description (plain dataclasses, fleet.launchfile.description) that `fleet render` checks and the
embedded runner both use, so that what render accepts is exactly what an agent runs."""

from fleet.launchfile.reader import read_launch_file, read_launch_text

__all__ = ["read_launch_file", "read_launch_text"]
