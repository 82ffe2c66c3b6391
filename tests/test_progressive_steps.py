"""The window refines the object view in steps as small as one sample (a slow machine, or a
costly material): each step must still draw every lobe, or the image converges to the wrong
value. Checked against the reference view's texel quadrature (an independent route)."""

import numpy as np
import pytest

from brdflab.io.resources import data_dir
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.object_view import ObjectRenderer, Progressive, RenderSettings

SIZE = 48
SAMPLES = 128
# a dim diffuse base under a glossy lobe that carries most of the light (the shares favour it)
TWO_LOBES = AnalyticMaterial("two lobes", "Linear", 3, [Lobe.create("Lambertian", [0.02, 0.03, 0.08]),
                                                        Lobe.create("BlinnPhong", [0.2] * 3, Exponent=100.0)])


@pytest.fixture(scope="module")
def renderer():
    from brdflab.render.context import create_context

    r = ObjectRenderer(create_context())
    r.set_environment(load_environment(data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr").downsampled(128, 64))
    r.set_material(TWO_LOBES)
    return r


def stepped(renderer, mode: str, step: int) -> tuple[np.ndarray, int]:
    """The reference view accumulated `step` samples at a time, as the window does."""
    image = Progressive(renderer, RenderSettings(mode=mode, width=SIZE, height=SIZE, samples=SAMPLES))
    try:
        while image.samples < SAMPLES:
            image.step(step)
        raw = np.frombuffer(image.texture.read(), np.float32).reshape(SIZE, SIZE, 4)[::-1]
    finally:
        image.release()
    return raw[:, :, :3] / image.samples, image.samples


@pytest.mark.parametrize("mode", ["fis", "mis"])
def test_one_sample_steps_converge_like_one_step_of_all(renderer, mode):
    inside = sphere_view(SIZE, SIZE).inside
    reference = environment_image(TWO_LOBES, renderer.environment, SIZE, SIZE)
    whole, _ = stepped(renderer, mode, SAMPLES)
    small, drawn = stepped(renderer, mode, 1)
    assert SAMPLES <= drawn <= SAMPLES + 2 * len(TWO_LOBES.lobes)  # every sample of a step is counted
    error_whole, error_small = relative_rmse(whole, reference, inside), relative_rmse(small, reference, inside)
    print(f"{mode}: relative RMSE to quadrature, one step {error_whole:.3f}, one-sample steps {error_small:.3f}")
    assert error_small < max(2 * error_whole, 0.05)
    assert small[inside].mean() == pytest.approx(reference[inside].mean(), rel=0.05)
