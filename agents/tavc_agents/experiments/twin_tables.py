"""Moved: the model twin's tables are measured by `tavc_env.twin.measure` (they need only
`tavc_env`). These names stay importable from here for saved work."""

from __future__ import annotations

from tavc_env.twin.measure import REFERENCE_PRESET as REFERENCE_PRESET
from tavc_env.twin.measure import RandomRun as RandomRun
from tavc_env.twin.measure import RandomTask as RandomTask
from tavc_env.twin.measure import allocation_for as allocation_for
from tavc_env.twin.measure import build_tables as build_tables
from tavc_env.twin.measure import random_allocation_run as random_allocation_run
