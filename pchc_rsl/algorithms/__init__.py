"""Learning algorithms."""

from pchc_rsl.algorithms.multi_critic_ppo import MultiCriticPPO

__all__ = ["MultiCriticPPO"]
