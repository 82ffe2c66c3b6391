"""Every model against its published formula, written here independently in scalar
math from angles (not from the vector code in brdflab), at hand-chosen points."""

import math

import numpy as np
import pytest

from brdflab.models import all_models, get_model

REQUIRED = {
    "Lambertian", "BlinnPhong", "LafortuneIso", "LafortuneAniso", "Ward", "WardDuer",
    "AshikhminShirley", "CookTorrance", "Kurt", "KurtDiffuse", "Phong", "OrenNayar", "Strauss",
    "AshikhminShirleyDiffuse", "Schwenk", "CookTorranceGGX",
}


def sph(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))


def angles(wi, wo):
    """θi, θo, θh, φh, wo·h (= wi·h) from first principles."""
    hx, hy, hz = (wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2])
    n = math.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx / n, hy / n, hz / n
    return (math.acos(wi[2]), math.acos(wo[2]), math.acos(hz), math.atan2(hy, hx),
            wo[0] * hx + wo[1] * hy + wo[2] * hz)


def schlick(f0, c):
    return f0 + (1 - f0) * (1 - c) ** 5


# (theta_i, phi_i, theta_o, phi_o) in degrees: off-specular, near-specular, grazing, anisotropic azimuths
POINTS = [(30, 0, 30, 180), (20, 10, 35, 200), (60, 45, 10, 250), (75, 120, 70, 290), (45, 90, 40, 260)]


def published(name, p, wi, wo):
    ti, to, th, ph, dh = angles(wi, wo)
    ci, co, ch = math.cos(ti), math.cos(to), math.cos(th)
    if name == "Lambertian":
        return 1.0
    if name == "BlinnPhong":
        n = p["Exponent"]
        return (n + 2) / (2 * math.pi) * ch**n
    if name == "Phong":
        n = p["Exponent"]
        r = (-wi[0], -wi[1], wi[2])
        return (n + 2) / (2 * math.pi) * max(0.0, sum(a * b for a, b in zip(r, wo))) ** n
    if name in ("LafortuneIso", "LafortuneAniso"):
        cx = p.get("Cx", p.get("Cxy"))
        cy = p.get("Cy", p.get("Cxy"))
        cz, n = p["Cz"], p["Exponent"]
        s = cx * wi[0] * wo[0] + cy * wi[1] * wo[1] + cz * wi[2] * wo[2]
        return (n + 2) / (2 * math.pi) * max(0.0, s) ** n / max(abs(cx), abs(cy), abs(cz)) ** n
    if name in ("Ward", "WardDuer"):
        ax, ay = p["ax"], p["ay"]
        e = math.exp(-math.tan(th) ** 2 * (math.cos(ph) ** 2 / ax**2 + math.sin(ph) ** 2 / ay**2))
        return e / (4 * math.pi * ax * ay * (math.sqrt(ci * co) if name == "Ward" else ci * co))
    if name == "AshikhminShirley":
        nu, nv = p["nu"], p["nv"]
        return (math.sqrt((nu + 1) * (nv + 1)) / (8 * math.pi) * ch ** (nu * math.cos(ph) ** 2 + nv * math.sin(ph) ** 2)
                * schlick(p["F0"], dh) / (dh * max(ci, co)))
    if name in ("CookTorrance",):
        m = p["m"]
        d = math.exp(-math.tan(th) ** 2 / m**2) / (math.pi * m**2 * ch**4)
        g = min(1, 2 * ch * co / dh, 2 * ch * ci / dh)
        return d * g * schlick(p["F0"], dh) / (4 * ci * co)
    if name == "CookTorranceGGX":
        a = p["m"]
        d = a**2 / (math.pi * ch**4 * (a**2 + math.tan(th) ** 2) ** 2)
        g1 = lambda t: 2 / (1 + math.sqrt(1 + a**2 * math.tan(t) ** 2))
        return d * g1(ti) * g1(to) * schlick(p["F0"], dh) / (4 * ci * co)
    if name == "Kurt":
        mx, my = p["mx"], p["my"]
        d = math.exp(-math.tan(th) ** 2 * (math.cos(ph) ** 2 / mx**2 + math.sin(ph) ** 2 / my**2)) / (math.pi * mx * my * ch**4)
        return schlick(p["F0"], dh) * d / (4 * dh * ci * co ** p["alpha"])
    if name == "KurtDiffuse":
        return 1 - schlick(p["F0"], dh)
    if name == "AshikhminShirleyDiffuse":
        return 28 / 23 * (1 - p["Rs"]) * (1 - (1 - ci / 2) ** 5) * (1 - (1 - co / 2) ** 5)
    if name == "OrenNayar":
        s2 = p["sigma"] ** 2
        A = 1 - 0.5 * s2 / (s2 + 0.33)
        B = 0.45 * s2 / (s2 + 0.09)
        phi_i, phi_o = math.atan2(wi[1], wi[0]), math.atan2(wo[1], wo[0])
        alpha, beta = max(ti, to), min(ti, to)
        return A + B * max(0.0, math.cos(phi_i - phi_o)) * math.sin(alpha) * math.tan(beta)
    if name == "Strauss":
        s, m, t, c = p["smoothness"], p["metalness"], p["transparency"], p["color"]
        kf, kg = 1.12, 1.01
        F = lambda x: (1 / (x - kf) ** 2 - 1 / kf**2) / (1 / (1 - kf) ** 2 - 1 / kf**2)
        G = lambda x: (1 / (1 - kg) ** 2 - 1 / (x - kg) ** 2) / (1 / (1 - kg) ** 2 - 1 / kg**2)
        xi, xo = ti / (math.pi / 2), to / (math.pi / 2)
        rd = (1 - s**3) * (1 - t)
        d = 1 - m * s
        rn = (1 - t) - rd
        rj = min(1, rn + (rn + 0.1) * F(xi) * G(xi) * G(xo))
        r = (-wi[0], -wi[1], wi[2])
        rs = rj * max(0.0, sum(a * b for a, b in zip(r, wo))) ** (3 / (1 - s))
        cs = 1 + m * (1 - F(xi)) * (c - 1)
        return rd * d * c / math.pi + rs * cs / ci
    if name == "Schwenk":
        s, m = p["smoothness"], p["metalness"]
        f0 = (1 - m) * 1 + m * p["tint"]
        e = 2 / (1.00392156862745 - s)
        return s * s / dh * schlick(f0, dh) * ch**e
    if name == "Principled":
        return principled_burley(p, wi, wo)
    raise AssertionError(name)


def principled_burley(p, wi, wo):
    """Burley 2012's BRDF Explorer `disney.brdf`, line by line in scalar math (its 2012 diffuse
    Fd, not Mitsuba's split form), with the three changes Mitsuba 3 makes (see the model's
    docstring): the untinted dielectric Fresnel exact at η(specular), and the clear coat
    without 1/(4 cos θi cos θo). Returns the luminance, as a colour lobe's `evaluate` does."""
    L, V = wi, wo
    H = [a + b for a, b in zip(L, V)]
    n = math.sqrt(sum(x * x for x in H))
    H = [x / n for x in H]
    NdotL, NdotV, NdotH, LdotH = L[2], V[2], H[2], sum(a * b for a, b in zip(L, H))
    sw = lambda u: min(1.0, max(0.0, 1 - u)) ** 5  # SchlickFresnel
    mix = lambda a, b, t: a * (1 - t) + b * t
    base = [p["base_color_r"], p["base_color_g"], p["base_color_b"]]
    lum = 0.212671 * base[0] + 0.715160 * base[1] + 0.072169 * base[2]
    ctint = [c / lum for c in base] if lum > 0 else [1.0, 1.0, 1.0]
    m, r = p["metallic"], p["roughness"]
    FL, FV = sw(NdotL), sw(NdotV)
    Fd90 = 0.5 + 2 * LdotH * LdotH * r
    Fd = mix(1.0, Fd90, FL) * mix(1.0, Fd90, FV)
    Fss90 = LdotH * LdotH * r
    Fss = mix(1.0, Fss90, FL) * mix(1.0, Fss90, FV)
    ss = 1.25 * (Fss * (1 / (NdotL + NdotV) - .5) + .5)
    aspect = math.sqrt(1 - p["anisotropic"] * .9)
    ax, ay = max(.001, r * r / aspect), max(.001, r * r * aspect)
    Ds = 1 / (math.pi * ax * ay * ((H[0] / ax) ** 2 + (H[1] / ay) ** 2 + NdotH * NdotH) ** 2)
    g1 = lambda v: 2 * v[2] / (v[2] + math.sqrt((v[0] * ax) ** 2 + (v[1] * ay) ** 2 + v[2] ** 2))
    Gs = g1(L) * g1(V) / (4 * NdotL * NdotV)  # disney.brdf's smithG_GGX_aniso product
    FH = sw(LdotH)
    eta = 2 / (1 - math.sqrt(0.08 * p["specular"])) - 1
    ct = math.sqrt(1 - (1 - LdotH ** 2) / eta ** 2)
    rs, rp = (LdotH - eta * ct) / (LdotH + eta * ct), (eta * LdotH - ct) / (eta * LdotH + ct)
    f_exact = 0.5 * (rs * rs + rp * rp)
    r0 = 0.08 * p["specular"]
    a2 = mix(.1, .001, p["clearcoat_gloss"]) ** 2
    Dr = (a2 - 1) / (math.pi * math.log(a2) * (1 + (a2 - 1) * NdotH * NdotH))
    g1c = lambda c: 2 * c / (c + math.sqrt(.0625 + c * c - .0625 * c * c))
    Fr = mix(.04, 1.0, FH)
    out = []
    for k in range(3):
        Cdlin = base[k]
        Fs = (1 - m) * (1 - p["specular_tint"]) * f_exact + m * mix(Cdlin, 1, FH) \
            + (1 - m) * p["specular_tint"] * mix(ctint[k] * r0, 1, FH)
        Csheen = mix(1, ctint[k], p["sheen_tint"])
        Fsheen = FH * p["sheen"] * Csheen
        value = ((1 / math.pi) * mix(Fd, ss, p["subsurface"]) * Cdlin + Fsheen) * (1 - m) + Gs * Fs * Ds \
            + .25 * p["clearcoat"] * g1c(NdotL) * g1c(NdotV) * Fr * Dr
        out.append(value)
    return 0.2126 * out[0] + 0.7152 * out[1] + 0.0722 * out[2]


PARAMS = {
    "BlinnPhong": {"Exponent": 35.0},
    "Phong": {"Exponent": 12.0},
    "LafortuneIso": {"Cxy": -0.7, "Cz": 0.55, "Exponent": 9.0},
    "LafortuneAniso": {"Cx": -0.9, "Cy": -0.4, "Cz": 0.6, "Exponent": 7.0},
    "Ward": {"ax": 0.15, "ay": 0.4},
    "WardDuer": {"ax": 0.3, "ay": 0.12},
    "AshikhminShirley": {"nu": 80.0, "nv": 15.0, "F0": 0.1},
    "CookTorrance": {"m": 0.35, "F0": 0.2},
    "CookTorranceGGX": {"m": 0.3, "F0": 0.6},
    "Kurt": {"mx": 0.2, "my": 0.45, "F0": 0.3, "alpha": 0.4},
    "KurtDiffuse": {"F0": 0.3},
    "AshikhminShirleyDiffuse": {"Rs": 0.2},
    "OrenNayar": {"sigma": 0.5},
    "Strauss": {"smoothness": 0.6, "metalness": 0.4, "transparency": 0.1, "color": 0.7},
    "Schwenk": {"smoothness": 0.7, "metalness": 0.6, "tint": 1.4},
    "Principled": {"base_color_r": 0.9, "base_color_g": 0.4, "base_color_b": 0.2, "metallic": 0.3, "subsurface": 0.6,
                   "specular": 0.7, "specular_tint": 0.4, "roughness": 0.35, "anisotropic": 0.6, "sheen": 0.5,
                   "sheen_tint": 0.7, "clearcoat": 0.8, "clearcoat_gloss": 0.6},
}


def test_every_required_model_is_registered():
    assert REQUIRED <= {m.name for m in all_models()}


@pytest.mark.parametrize("model", all_models(), ids=lambda m: m.name)
def test_model_matches_published_formula(model):
    p = {**model.defaults(), **PARAMS.get(model.name, {})}
    for (ti, pi, to, po) in POINTS:
        wi, wo = sph(ti, pi), sph(to, po)
        expected = published(model.name, p, wi, wo)
        got = float(model.evaluate(np.array(wi), np.array(wo), p))
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-300), (ti, pi, to, po)


def test_hand_computed_values():
    """A few values worked out by hand, not by any code."""
    wi, wo = np.array(sph(30, 0)), np.array(sph(30, 180))  # mirror pair: h = n
    # Blinn–Phong at h = n: (n+2)/(2π) = 22/(2π) for n = 20
    assert float(get_model("BlinnPhong").evaluate(wi, wo, {"Exponent": 20.0})) == pytest.approx(22 / (2 * math.pi))
    # Ward at h = n: 1/(4π ax ay cos30°)
    assert float(get_model("Ward").evaluate(wi, wo, {"ax": 0.1, "ay": 0.2})) == pytest.approx(
        1 / (4 * math.pi * 0.02 * math.cos(math.radians(30))))
    # Cook–Torrance at h = n, F0 = 1: D = 1/(π m²), G = 1 → 1/(π m² · 4 cos²30°) = 1/(π m² · 3)
    assert float(get_model("CookTorrance").evaluate(wi, wo, {"m": 0.5, "F0": 1.0})) == pytest.approx(1 / (math.pi * 0.25 * 3))
    # Lafortune with Cxy = −1, Cz = 1 is Phong: value (n+2)/(2π) at the mirror direction
    assert float(get_model("LafortuneIso").evaluate(wi, wo, {"Cxy": -1.0, "Cz": 1.0, "Exponent": 10.0})) == pytest.approx(12 / (2 * math.pi))
    # Oren–Nayar with σ = 0 is Lambertian
    assert float(get_model("OrenNayar").evaluate(wi, np.array(sph(50, 10)), {"sigma": 0.0})) == pytest.approx(1.0)


@pytest.mark.parametrize("model", all_models(), ids=lambda m: m.name)
def test_zero_below_the_surface(model):
    below = np.array(sph(100, 0))
    above = np.array(sph(30, 180))
    assert float(model.evaluate(below, above)) == 0.0
    assert float(model.evaluate(above, below)) == 0.0


@pytest.mark.parametrize("model", [m for m in all_models() if m.reciprocal], ids=lambda m: m.name)
def test_helmholtz_reciprocity(model, rng):
    from conftest import random_upper

    wi, wo = random_upper(rng, 2000), random_upper(rng, 2000)
    p = {**model.defaults(), **PARAMS.get(model.name, {})}
    a, b = model.evaluate(wi, wo, p), model.evaluate(wo, wi, p)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-300)


@pytest.mark.parametrize("name", ["Kurt", "Strauss"])
def test_non_reciprocal_models_are_declared_so(name, rng):
    from conftest import random_upper

    model = get_model(name)
    assert not model.reciprocal
    wi, wo = random_upper(rng, 500), random_upper(rng, 500)
    p = {**model.defaults(), **PARAMS[name]}
    assert not np.allclose(model.evaluate(wi, wo, p), model.evaluate(wo, wi, p))


def test_kurt_is_reciprocal_when_alpha_is_one(rng):
    from conftest import random_upper

    wi, wo = random_upper(rng, 500), random_upper(rng, 500)
    p = {"mx": 0.2, "my": 0.3, "F0": 0.4, "alpha": 1.0}
    m = get_model("Kurt")
    np.testing.assert_allclose(m.evaluate(wi, wo, p), m.evaluate(wo, wi, p), rtol=1e-9)


def test_parameters_broadcast_for_batched_evaluation(rng):
    """A fitter evaluates K parameter sets over N directions in one call."""
    from conftest import random_upper

    wi, wo = random_upper(rng, 50), random_upper(rng, 50)
    m = get_model("Ward")
    ax = np.array([0.1, 0.2, 0.3])[:, None]
    batched = m.evaluate(wi, wo, {"ax": ax, "ay": 0.2})
    assert batched.shape == (3, 50)
    for k in range(3):
        np.testing.assert_allclose(batched[k], m.evaluate(wi, wo, {"ax": float(ax[k, 0]), "ay": 0.2}))
