"""Vectorised environments that follow the pchc-rsl contract (DESIGN.md): preference group, reward_groups."""
