"""Writing parameter files and world files: block mappings, one line per value, lists of
scalars in flow style, lists of mappings as block sequences.

A small exact emitter rather than yaml.dump: these files hold only validated names and plain
values (bool, int, float, string, lists), and a 1,000-robot fleet writes thousands of them.
Strings are JSON-quoted (valid YAML double-quoted scalars) unless both rcl and PyYAML read them
bare as the same string; floats always carry a '.' or an exponent with a '.', so every YAML
reader (rcl, PyYAML) reads them as floats.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

from fleet.spec.rcl_types import rcl_scalar

# Strings that read back as the same string when written bare: names, namespaces, file names.
_PLAIN = re.compile(r"[A-Za-z_/][A-Za-z0-9_./-]*")
_YAML_WORDS = {"true", "false", "yes", "no", "on", "off", "null", "y", "n"}
_PLAIN_KEY = re.compile(r"[A-Za-z_/.][A-Za-z0-9_/.]*")


def scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        text = repr(value)
        if "e" in text and "." not in text.split("e")[0]:
            mantissa, exponent = text.split("e")
            text = f"{mantissa}.0e{exponent}"
        return text
    if isinstance(value, str):
        # rcl reads `inf`, `nan` and `Infinity` bare as doubles: those are quoted too.
        if _PLAIN.fullmatch(value) and value.lower() not in _YAML_WORDS and type(rcl_scalar(value)) is str:
            return value
        return json.dumps(value, ensure_ascii=True)
    if value is None:
        return "null"
    raise TypeError(f"cannot write {type(value).__name__} {value!r} to a parameter or world file")


def emit(tree: dict[str, Any], indent: int = 0) -> str:
    """`key: value` lines for a nested mapping of validated keys."""
    pad = "  " * indent
    lines = []
    for key, value in tree.items():
        label = mapping_key(key)
        if isinstance(value, dict):
            if value:
                lines.append(f"{pad}{label}:\n{emit(value, indent + 1)}")
            else:
                lines.append(f"{pad}{label}: {{}}\n")
        elif isinstance(value, list) and value and all(isinstance(item, dict) for item in value):
            lines.append(f"{pad}{label}:\n")
            for item in value:
                item_text = emit(item, indent + 1)
                lines.append(f"{pad}- {item_text[len(pad) + 2 :]}" if item else f"{pad}- {{}}\n")
        elif isinstance(value, list):
            lines.append(f"{pad}{label}: [{', '.join(scalar(item) for item in value)}]\n")
        else:
            lines.append(f"{pad}{label}: {scalar(value)}\n")
    return "".join(lines)


def mapping_key(key: str) -> str:
    # Keys are ROS names, parameter names or fully-qualified node names (/robot1/controller):
    # all plain YAML scalars.  Quote anything else rather than trust it.
    if _PLAIN_KEY.fullmatch(key) and key.lower() not in _YAML_WORDS:
        return key
    return json.dumps(key, ensure_ascii=True)
