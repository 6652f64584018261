"""Learning robots: the paper's TAVC Q-learner (`tavc`) and its action selection rules
(`selection`: epsilon-greedy and Boltzmann softmax)."""
