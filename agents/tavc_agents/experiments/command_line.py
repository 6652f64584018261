"""Reading `KEY=VALUE` items of a command line (`tavc trial --set source_service_s=15`,
`--param temperature=0.01`): the library's reader, which the `tavc` command and the studies use."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any


def parse_key_values(items: Sequence[str], option: str, example: str) -> dict[str, Any]:
    """`KEY=VALUE` items (as given to `option`) as a dict: values that parse as JSON (numbers,
    true/false, lists) are used as such, anything else as a string; whoever receives them then
    names any key or value it does not accept. A ValueError shows `example` for a malformed one."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ValueError(f"{option} {item!r} is invalid; allowed: KEY=VALUE, e.g. {example}")
        try:
            out[key] = json.loads(text)
        except json.JSONDecodeError:
            out[key] = text
    return out
