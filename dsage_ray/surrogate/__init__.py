"""The deep surrogate model: networks, the dataset of real evaluations, training and prediction."""

from dsage_ray.surrogate.dataset import SurrogateDataset, Targets, TrainingWindow
from dsage_ray.surrogate.models import (
    MeasurePredictor,
    ModelOutput,
    OccupancyPredictor,
    OneStageModel,
    TwoStageModel,
    pad_to_power_of_two,
)
from dsage_ray.surrogate.surrogate import Prediction, Surrogate, resolve_device

__all__ = [
    "MeasurePredictor",
    "ModelOutput",
    "OccupancyPredictor",
    "OneStageModel",
    "Prediction",
    "Surrogate",
    "SurrogateDataset",
    "Targets",
    "TrainingWindow",
    "TwoStageModel",
    "pad_to_power_of_two",
    "resolve_device",
]
