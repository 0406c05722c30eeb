"""Rollout storage with one reward and value column per critic."""

from pchc_rsl.storage.multi_critic_storage import MultiCriticRolloutStorage

__all__ = ["MultiCriticRolloutStorage"]
