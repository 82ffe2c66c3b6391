"""Where a GLSL-only model is evaluated on the CPU side: the render layer's headless context.

The core never imports OpenGL. A model whose only definition is GLSL (every BRDF Explorer
file) cannot be evaluated without it, so the core asks for an evaluator here; the render
layer provides one (`brdflab.render.model_eval`), loaded on first use. Without OpenGL the
request fails with one line that says so, and every formula model still works.
"""

from __future__ import annotations

import importlib
from typing import Protocol

import numpy as np

from brdflab.errors import BRDFLabError

PROVIDER = "brdflab.render.model_eval"  # the module that installs the evaluator when imported


class GlslEvaluator(Protocol):
    def evaluate(self, model, wi: np.ndarray, wo: np.ndarray, params: list) -> np.ndarray:
        """(N, 3) float64 values of the model's GLSL at the direction pairs."""

    def check(self, model) -> None:
        """Compile the model's GLSL; BRDFLabError naming the file's line on failure."""


_evaluator: GlslEvaluator | None = None


def install(evaluator: GlslEvaluator) -> None:
    global _evaluator
    _evaluator = evaluator


def glsl_evaluator() -> GlslEvaluator:
    if _evaluator is None:
        try:
            importlib.import_module(PROVIDER)  # a plug-in: it calls install()
        except ImportError as e:
            raise BRDFLabError(f"evaluating a GLSL model needs OpenGL (moderngl): {e}") from None
    if _evaluator is None:
        raise BRDFLabError("no GLSL evaluator is installed")
    return _evaluator
