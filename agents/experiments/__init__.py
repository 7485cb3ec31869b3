"""Experiments over the envs and policies: reproduction and evaluation commands (see filters.experiments
for the runner, statistics and report writers they share)."""
