"""Training runners."""

from pchc_rsl.runners.checkpoint import load_checkpoint
from pchc_rsl.runners.pchc_runner import (NonFiniteTraining, PCHCRunner, PhysicsOverflowStopped, TrainingInterrupted,
                                          TrainingStopped)

__all__ = ["NonFiniteTraining", "PCHCRunner", "PhysicsOverflowStopped", "TrainingInterrupted", "TrainingStopped",
           "load_checkpoint"]
