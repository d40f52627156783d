"""DDPG training, evaluation, export and reports (needs torch; the policy node does not)."""
