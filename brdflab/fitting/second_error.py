"""Every fit reports both numbers (issue 34): a fit by a sample metric its image error under
the image metric's maps, a fit by the image metric its Ngan error over every sample, so that
neither number is judged alone (a principled metal that the sample metric called better
rendered as a pink ceramic)."""

from __future__ import annotations

from collections.abc import Sequence

from brdflab.fitting.defaults import DEFAULT_METRIC
from brdflab.fitting.image_metric import SceneImages
from brdflab.fitting.metrics import metric_error
from brdflab.fitting.samples import SampleSet, samples_of
from brdflab.lighting.envmap import EnvironmentMap


def second_error(material, source, fitted: SampleSet, maps: Sequence[EnvironmentMap] | None = None) -> dict:
    """The number the fit was not judged by, as FitStatistics entries: imageError and
    imageMaps (comma-separated), or sampleError and sampleMetric."""
    if isinstance(fitted, SceneImages):
        return {"sampleError": metric_error(material, samples_of(source), DEFAULT_METRIC),
                "sampleMetric": DEFAULT_METRIC}
    scene = SceneImages.of_source(source, maps)
    return {"imageError": scene.errors([material])[0], "imageMaps": ",".join(q.name for q in scene.quadratures)}


def image_error(material, source, maps: Sequence[EnvironmentMap] | None = None) -> float:
    """The image error of `material` against `source` under `maps` (default: the metric's three)."""
    return SceneImages.of_source(source, maps).errors([material])[0]


def describe(second: dict) -> str:
    """One phrase for a human line: 'image error 0.1157 under A, B, C' or 'Ngan error … on all samples'."""
    if "imageError" in second:
        return f"image error {second['imageError']:.4g} under {second['imageMaps'].replace(',', ', ')}"
    if "sampleError" in second:
        return f"{second['sampleMetric']} error {second['sampleError']:.6g} on all samples"
    return ""
