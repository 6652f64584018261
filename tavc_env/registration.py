"""Registration of the arena in PettingZoo's environment registry (PettingZoo >= 1.27 has one).

After `import tavc_env`, `pettingzoo.make("parallel", "tavc/tavc_arena-v0", preset=...)` and
`pettingzoo.make("aec", "tavc/tavc_arena-v0")` build the environments.
"""

from __future__ import annotations

import pettingzoo

REGISTRY_ID = "tavc/tavc_arena-v0"


def register() -> None:
    """Register both views once; a no-op on PettingZoo versions without a registry."""
    if not hasattr(pettingzoo, "register"):
        return
    if REGISTRY_ID not in pettingzoo.parallel_registry:
        pettingzoo.register("parallel", REGISTRY_ID, entry_point="tavc_env.env:parallel_env")
    if REGISTRY_ID not in pettingzoo.aec_registry:
        pettingzoo.register("aec", REGISTRY_ID, entry_point="tavc_env.env:env")
