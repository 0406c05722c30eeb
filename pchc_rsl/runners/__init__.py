"""Training runners."""

from pchc_rsl.runners.checkpoint import load_checkpoint
from pchc_rsl.runners.pchc_runner import NonFiniteTraining, PCHCRunner, TrainingInterrupted, TrainingStopped

__all__ = ["NonFiniteTraining", "PCHCRunner", "TrainingInterrupted", "TrainingStopped", "load_checkpoint"]
