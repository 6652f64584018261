"""The package's questions, one module each, a short program over the study contract
(`tavc_agents.experiments.study`): the settings of a study (a frozen dataclass that is also its
command line), the trials it runs and the report it writes. The scripts in `benchmarks/` and
`tavc bench` are thin command lines over these modules: `run_study(module, argv, description)`.

`STUDIES` names them; modules are imported only when used, so the command line starts fast.
"""

from __future__ import annotations

import importlib
from types import ModuleType

STUDIES: dict[str, str] = {
    name: f"tavc_agents.studies.{name}"
    for name in (
        "table1",
        "differentiation",
        "interference",
        "dt_fidelity",
        "long_run",
        "throughput",
        "tavc_model",
        "allocators",
        "vacancy_chain",
        "liveness",
        "congestion_design",
        "regime_map",
        "passing",
        "twin_audit",
        "twin_batch",
        "twin_curve",
        "cli_startup",
        "vector_throughput",
    )
}
"""Study name -> module."""


def load(name: str) -> ModuleType:
    """The module of study `name`; a ValueError naming the known ones otherwise."""
    if name not in STUDIES:
        raise ValueError(f"study {name!r} is unknown; allowed: {sorted(STUDIES)}")
    return importlib.import_module(STUDIES[name])
