"""Training runners."""

from pchc_rsl.runners.pchc_runner import PCHCRunner, load_checkpoint

__all__ = ["PCHCRunner", "load_checkpoint"]
