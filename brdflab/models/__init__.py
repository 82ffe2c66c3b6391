"""Lobe models: one module per model, collected in `registry`."""

from brdflab.models.base import LobeModel, Parameter
from brdflab.models.registry import all_models, get_model, model_names

__all__ = ["LobeModel", "Parameter", "all_models", "get_model", "model_names"]
