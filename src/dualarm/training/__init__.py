"""Training runs of DADDPG: the loop, its run directory, evaluation and environment batches."""

from dualarm.training.config import TrainConfig
from dualarm.training.loop import Trainer, TrainingDiverged, resume, train

__all__ = ["TrainConfig", "Trainer", "TrainingDiverged", "train", "resume"]
