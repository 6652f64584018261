"""The fuzzing harness (issue 12, item 7): hypothesis strategies over arena configurations, action
streams, seeds and stored trial files, checked against the package's promises:

* a valid configuration runs an episode without a Python exception and without two robots (or a
  robot and a wall) overlapping by more than a tenth of the robot radius;
* an invalid one raises a ValueError whose message names the offending field;
* any value of any type in a number field of an arena, of its parts or of the helper constructors
  is either accepted, stored as a plain float or int, and runs, or refused naming the field
  (`test_number_types.py`; its outcomes are hypothesis events: `--hypothesis-show-statistics`);
* a bad action or seed raises a ValueError naming it and changes nothing; the AEC view and the
  parallel view agree step for step on the same actions;
* any sequence of calls to the AEC view (reset, step, observe, last, agent_iter, state; before
  reset, mid-episode, after the end; valid and unknown agents and actions) does what the AEC
  contract says or raises the package's ValueError, changing nothing;
* a truncated, garbled or edited trial file raises `CorruptFileError` (a ValueError) naming the
  file, and a resumed sweep runs that trial again; no trial file is lost or left half-written;
* a run folder whose trial slots or provenance are replaced by folders, links, FIFOs, devices,
  garbled, non-finite or oversized files resumes (damaged trials named, moved aside and rerun,
  intact ones resumed) or is refused in one line, and never hangs (`test_run_folders.py`).

Two profiles (tests/fuzz/conftest.py): the default runs a few hundred examples in all, the same
ones every time, as part of the normal test run; the long one draws 25 times as many, fresh each
run (failures are replayed from .hypothesis/tavc-fuzz):

    TAVC_FUZZ=long python -m pytest tests/fuzz -n 2 -q
"""
