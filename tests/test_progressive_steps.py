"""The window refines the object view in steps as small as one sample (a slow machine, or a
costly material). A step draws the next rows of one stratified set, so the finished image is
the one `render` makes in one step — same stratification, same filter footprint — and what
the window shows has the error Auto lighting predicts. Once, a step of fewer samples than
lobes drew only a Lambertian's sample and the image converged 40 % off; later, small steps
were independent random sets and lost the stratification (4.4 % instead of 1.5 % at 64)."""

import numpy as np
import pytest

from brdflab.io.resources import data_dir
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.reference_view import environment_image, pixel_relative_rmse, relative_rmse, sphere_view
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.render.object_view import ObjectRenderer, Progressive, RenderSettings

SIZE = 48
SAMPLES = 64
# a dim diffuse base under a glossy lobe that carries most of the light
TWO_LOBES = AnalyticMaterial("two lobes", "Linear", 3, [Lobe.create("Lambertian", [0.02, 0.03, 0.08]),
                                                        Lobe.create("BlinnPhong", [0.2] * 3, Exponent=100.0)])


@pytest.fixture(scope="module")
def renderer():
    from brdflab.render.context import create_context

    r = ObjectRenderer(create_context())
    r.set_environment(load_environment(data_dir("resources") / "envmaps" / "venice_sunset_1k.hdr").downsampled(128, 64))
    r.set_material(TWO_LOBES)
    return r


def stepped(renderer, mode: str, step: int, seed: int | None = None, set_size: int = SAMPLES) -> tuple[np.ndarray, int]:
    """The reference view accumulated `step` samples at a time up to SAMPLES, as the window does,
    of a set of `set_size` (in the renderer's own context: a window test before this one leaves
    another context current, where creating the image's texture failed)."""
    with renderer.ctx:
        image = Progressive(renderer, RenderSettings(mode=mode, width=SIZE, height=SIZE, samples=set_size), seed=seed)
        try:
            while image.drawn < SAMPLES:
                image.step(step)
            raw = np.frombuffer(image.texture.read(), np.float32).reshape(SIZE, SIZE, 4)[::-1]
        finally:
            image.release()
    return raw[:, :, :3] / image.samples, image.drawn


@pytest.mark.parametrize("mode", ["fis", "mis"])
def test_small_steps_finish_the_image_one_step_makes(renderer, mode):
    inside = sphere_view(SIZE, SIZE).inside
    whole, _ = stepped(renderer, mode, SAMPLES)
    for step in (1, 3):  # 3: steps that do not divide the set
        small, drawn = stepped(renderer, mode, step)
        assert drawn == SAMPLES
        np.testing.assert_allclose(small[inside], whole[inside], rtol=1e-4, atol=1e-6)
    # and that image is the right one: the reference view's texel quadrature, an independent route
    reference = environment_image(TWO_LOBES, renderer.environment, SIZE, SIZE)
    error = relative_rmse(whole, reference, inside)
    print(f"{mode}: relative RMSE to quadrature at {SAMPLES} samples {error:.3f}")
    assert error < 0.05


def test_a_seeded_image_in_small_steps_is_its_one_step_image_too(renderer):
    """Seeded images (independent estimates, as the lighting study takes them) rotate their
    first set; stepping must not change which set that is."""
    inside = sphere_view(SIZE, SIZE).inside
    whole, _ = stepped(renderer, "fis", SAMPLES, seed=5)
    small, _ = stepped(renderer, "fis", 1, seed=5)
    other, _ = stepped(renderer, "fis", SAMPLES, seed=6)
    np.testing.assert_allclose(small[inside], whole[inside], rtol=1e-4, atol=1e-6)
    assert np.abs(other[inside] - whole[inside]).max() > 1e-3  # a different seed is a different set


@pytest.mark.parametrize("n", [85, 171, 256, 1024])
def test_every_run_of_a_set_drawn_in_pieces_is_spread_over_the_square(n):
    """`pieces_order` puts a strategy's points so that the first k of them cover the unit
    square: in a √k × √k grid no cell holds more than two of the first 16 or 64 (one each where
    n is a power of two). In the set's own order the first quarter lay in u1 < 0.25."""
    from brdflab.lighting.sampling_sets import hammersley, spread_order

    points = hammersley(n)
    for order, most in ((spread_order(n), 1 if n & (n - 1) == 0 else 2), (np.arange(n), None)):
        for k in (16, 64):
            grid = int(np.sqrt(k))
            counts = np.histogram2d(*points[order[:k]].T, bins=grid, range=[[0, 1], [0, 1]])[0]
            if most is None:
                assert (counts == 0).sum() >= grid  # the set's own order: the cells of u1 < k / n only
            else:
                assert counts.max() <= most, (n, k, counts)
    assert sorted(spread_order(n)) == list(range(n))


def test_a_set_drawn_in_pieces_keeps_its_rows_and_each_strategys_places():
    from brdflab.lighting.sampling_sets import lobe_shares, mis_sample_set, pieces_order

    data, _, _ = mis_sample_set(lobe_shares(TWO_LOBES), 256)
    ordered = data[pieces_order(data, np.random.default_rng(1))]
    np.testing.assert_array_equal(ordered[:, 2], data[:, 2])  # the lobes and the map interleaved as before
    assert sorted(map(tuple, ordered)) == sorted(map(tuple, data))  # the same set


@pytest.mark.parametrize("mode, set_size, bound", [("fis", 2 * SAMPLES, 2.0), ("mis", 4 * SAMPLES, 1.75)])
def test_the_image_on_the_way_is_nearly_as_good_as_a_set_of_its_size(renderer, mode, set_size, bound):
    """The window draws a set a few samples at a time: after 64 of them its image's error per
    pixel, against the texel quadrature, is within `bound` × a finished set of 64's: MIS of 256
    1.61× here (shuffled rows, drawn until the spread order, were 2.26×, 3.6× on the default
    scene, docs/mis.md); FIS of 128 1.72×, its filter footprint twice its samples' (FIS of 256
    shows a finished set of 64 meanwhile, the test above)."""
    inside = sphere_view(SIZE, SIZE).inside
    reference = environment_image(TWO_LOBES, renderer.environment, SIZE, SIZE)
    part, drawn = stepped(renderer, mode, 1, set_size=set_size)
    on_the_way = pixel_relative_rmse(part, reference, inside)
    finished, _ = stepped(renderer, mode, SAMPLES)
    whole = pixel_relative_rmse(finished, reference, inside)
    print(f"{mode}: {SAMPLES} of {set_size} {on_the_way:.4f}, a set of {SAMPLES} {whole:.4f}")
    assert drawn == SAMPLES and on_the_way < bound * whole


def test_a_long_fis_image_shows_a_finished_set_of_64_first_and_ends_as_render(renderer):
    """FIS's filter footprint is its set's size, so 64 samples of a set of 256 are noisier than
    a set of 64 (2.1 against 1.0–1.5 % per pixel on the default scene, docs/mis.md). An FIS
    image of 256 drawn in small steps shows a finished set of 64 (the image `render` makes of
    64) after 64 samples, keeps it until its own set is complete, and then is `render`'s image
    of 256; MIS, whose samples have no footprint, draws its set alone."""
    from brdflab.render.object_view import PREVIEW

    def shown(image):
        return np.frombuffer(image.texture.read(), np.float32).reshape(SIZE, SIZE, 4)[::-1, :, :3] / image.samples

    inside = sphere_view(SIZE, SIZE).inside
    big = RenderSettings(mode="fis", width=SIZE, height=SIZE, samples=4 * SAMPLES)
    with renderer.ctx:
        whole = {n: renderer.render(RenderSettings(mode="fis", width=SIZE, height=SIZE, samples=n)) for n in (PREVIEW, 4 * SAMPLES)}
        image = Progressive(renderer, big)
        try:
            seen = {}
            while not image.complete:
                image.step(5)
                seen[image.drawn] = (image.samples, shown(image))
            assert image.drawn == image.needed == PREVIEW + 4 * SAMPLES
            end = shown(image)
        finally:
            image.release()
        mis = Progressive(renderer, RenderSettings(mode="mis", width=SIZE, height=SIZE, samples=4 * SAMPLES))
        try:
            while not mis.complete:
                mis.step(5)
            assert mis.drawn == mis.needed == 4 * SAMPLES
        finally:
            mis.release()
    at_64 = min(k for k in seen if k >= PREVIEW)
    assert seen[at_64][0] == PREVIEW
    np.testing.assert_allclose(seen[at_64][1][inside], whole[PREVIEW][inside], rtol=1e-4, atol=1e-6)
    assert all(samples == PREVIEW for k, (samples, _) in seen.items() if PREVIEW <= k < image.needed)
    np.testing.assert_allclose(end[inside], whole[4 * SAMPLES][inside], rtol=1e-4, atol=1e-6)
