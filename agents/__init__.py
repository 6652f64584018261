"""Agents for the tavc arena: the TAVC Q-learners and baseline allocators (see issue 3 onward)."""
