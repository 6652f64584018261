# TEMPORARY re-export for the studies being moved out; removed when branch floors merges
from tavc_agents.experiments.timing import random_choice_run as random_choice_run
from tavc_env.measurement import FixedAllocation as FixedAllocation
from tavc_env.measurement import FixedRun as FixedRun
from tavc_env.measurement import SpacingMonitor as SpacingMonitor
from tavc_env.measurement import physics_floor as physics_floor
from tavc_env.measurement import physics_replay as physics_replay
from tavc_env.measurement import run_fixed as run_fixed
from tavc_env.measurement import two_circuit_allocation as two_circuit_allocation
