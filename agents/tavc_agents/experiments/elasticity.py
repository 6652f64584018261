# TEMPORARY re-export for the studies being moved out; removed when branch floors merges
from tavc_agents.analysis.elasticity import CELLS as CELLS
from tavc_agents.analysis.elasticity import FAST as FAST
from tavc_agents.analysis.elasticity import PER_CLASS as PER_CLASS
from tavc_agents.analysis.elasticity import SLOW as SLOW
from tavc_agents.analysis.elasticity import cross_allocation as cross_allocation
