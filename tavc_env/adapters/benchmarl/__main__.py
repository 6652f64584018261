"""`python -m tavc_env.adapters.benchmarl algorithm=... task=tavc/<task> ...`: BenchMARL's command
line with the `tavc` tasks (`tavc_env.adapters.benchmarl.main`)."""

from tavc_env.adapters.benchmarl import main

main()
