"""Registration of the arena in PettingZoo's environment registry (PettingZoo >= 1.27 has one).

After `import tavc_env`, `pettingzoo.make("parallel", "tavc/tavc_arena-v1", preset=...)` and
`pettingzoo.make("aec", "tavc/tavc_arena-v1")` build the environments; `tavc/tavc_arena-v0` builds
v0 (`tavc_env.v0`), kept for saved work. Every scenario of the suite (`tavc_env.scenarios`) has an
id of its own, e.g. `pettingzoo.make("parallel", "tavc/priority_shifts-v0")`.
"""

from __future__ import annotations

from typing import Any

import pettingzoo

from tavc_env.scenarios import SCENARIOS

REGISTRY_ID = "tavc/tavc_arena-v1"
REGISTRY_ID_V0 = "tavc/tavc_arena-v0"
_ENTRY_POINTS = {REGISTRY_ID: "tavc_env.env", REGISTRY_ID_V0: "tavc_env.v0"}


def register() -> None:
    """Register both views of both versions of the arena, and of every scenario of
    `tavc_env.scenarios.SCENARIOS` (`tavc/<name>-v<version>`), once; a no-op on PettingZoo
    versions without a registry."""
    if not hasattr(pettingzoo, "register"):
        return
    entries: list[tuple[str, str, dict[str, Any]]] = [
        (name, module, {}) for name, module in _ENTRY_POINTS.items()
    ]
    entries += [(s.id, "tavc_env.scenarios", {"scenario": s.name}) for s in SCENARIOS.values()]
    for name, module, kwargs in entries:
        if name not in pettingzoo.parallel_registry:
            pettingzoo.register(
                "parallel", name, entry_point=f"{module}:parallel_env", kwargs=dict(kwargs)
            )
        if name not in pettingzoo.aec_registry:
            pettingzoo.register("aec", name, entry_point=f"{module}:env", kwargs=dict(kwargs))
