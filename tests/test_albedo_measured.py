"""Issue 30 §1: the directional albedo the window plots for measured data converges, near
mirrors included (MERL chrome jumped 0.04–0.34 from one view angle to the next)."""

import numpy as np
from conftest import DATA, needs_shared

THETA = np.radians(np.linspace(0, 85, 18))  # the plot's view angles


def _slice_quadrature(table, theta: np.ndarray) -> np.ndarray:
    """An independent quadrature of a bivariate slice: per view, a fine (θi, φi) product rule
    whose θi nodes crowd around the mirror direction (where chrome's peak lies)."""
    from brdflab.geometry.vec import spherical_to_cartesian
    from brdflab.gui.panels import _luminance

    out = []
    for t in theta:
        u = (np.arange(2400) + 0.5) / 2400  # θi by t + s·|s|·(π/2 spread): dense at θi = θo
        ti = t + np.sign(u - 0.5) * ((2 * u - 1) ** 2) * np.pi
        dti = 4 * np.abs(2 * u - 1) * np.pi / 2400
        keep = (ti > 0) & (ti < np.pi / 2)
        ti, dti = ti[keep], dti[keep]
        # φi: dense around the mirror azimuth π (the view is at φo = 0)
        v = (np.arange(720) + 0.5) / 720
        pi_ = np.pi + np.sign(v - 0.5) * ((2 * v - 1) ** 2) * np.pi
        dpi = 4 * np.abs(2 * v - 1) * np.pi / 720
        T, P = np.meshgrid(ti, pi_, indexing="ij")
        wi = spherical_to_cartesian(T.ravel(), P.ravel())
        wo = np.broadcast_to(spherical_to_cartesian(t, 0.0), wi.shape)
        f = _luminance(table.evaluate(wi, wo))
        w = (np.cos(T) * np.sin(T) * dti[:, None] * dpi[None, :]).ravel()
        out.append(float((f * w).sum()))
    return np.array(out)


@needs_shared("merl_slices", "chrome-steel.slice")
def test_the_plotted_albedo_of_measured_chrome_converges():
    from brdflab.gui.panels import albedo_curve
    from brdflab.sources.measured import read_slice

    chrome = read_slice(DATA / "merl_slices" / "chrome-steel.slice")
    plotted = albedo_curve(chrome, THETA)
    reference = _slice_quadrature(chrome, THETA[:-1:2])  # 0.07–0.12 (the old estimate: 0.05–0.34)
    np.testing.assert_allclose(plotted[:-1:2], reference, rtol=0.01)
    # smooth from one angle to the next below grazing (the old estimate jumped 7×)
    assert np.abs(np.diff(plotted[:-2])).max() < 0.2 * plotted[:-2].max()


def test_the_plotted_albedo_of_a_tabulated_mirror_equals_its_model():
    from brdflab.gui.panels import albedo_curve
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources.measured import tabulate

    mirror = AnalyticMaterial("mirror", "Linear", 3, [Lobe.create("CookTorrance", [0.8] * 3, m=0.03, F0=0.9)])
    table = tabulate(mirror, phi_d_samples=1)
    theta = THETA[:14]  # below 65°: the model's own importance sampling is the reference there
    np.testing.assert_allclose(albedo_curve(table, theta), albedo_curve(mirror, theta), rtol=0.03)
