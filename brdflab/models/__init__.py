"""Lobe models: one module per model, collected in `registry`."""

from .base import LobeModel, Parameter
from .registry import all_models, get_model, model_names

__all__ = ["LobeModel", "Parameter", "all_models", "get_model", "model_names"]
