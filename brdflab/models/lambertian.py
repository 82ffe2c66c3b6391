"""Lambertian: a constant lobe of value 1; a Linear scaling factor is ρd/π."""

import numpy as np

from brdflab.models.base import CosineSampled
from brdflab.models.registry import register


@register
class Lambertian(CosineSampled):
    name = "Lambertian"
    summary = "Ideal diffuse reflection: value 1 (scale it by ρd/π)."
    reference = "Lambert 1760; BRDFLab (Forés et al. 2009)"

    def _value(self, wi, wo, p):
        return np.ones(np.broadcast_shapes(wi.shape[:-1], wo.shape[:-1]))

