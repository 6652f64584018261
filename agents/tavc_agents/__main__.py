"""`python -m tavc_agents ...`: the `tavc` command, where its script is not on PATH."""

import sys

from tavc_agents.cli import main

sys.exit(main())
