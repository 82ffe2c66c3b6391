// Oren–Nayar qualitative model (scale by ρ/π).  p = [sigma]
float brdf_OrenNayar(vec3 wi, vec3 wo, float p[NP]) {
    float s2 = p[0] * p[0];
    float A = 1.0 - 0.5 * s2 / (s2 + 0.33);
    float B = 0.45 * s2 / (s2 + 0.09);
    float ci = clamp(wi.z, -1.0, 1.0), co = clamp(wo.z, -1.0, 1.0);
    float si = sqrt(1.0 - ci * ci), so = sqrt(1.0 - co * co);
    float d = si * so;
    float cos_dphi = d > TINY ? (wi.x * wo.x + wi.y * wo.y) / d : 0.0;
    float sin_a = ci < co ? si : so;
    float sin_b = ci < co ? so : si;
    return A + B * max(cos_dphi, 0.0) * sin_a * sin_b / max(max(ci, co), TINY);
}
vec3 sample_OrenNayar(vec3 wo, vec2 u, float p[NP]) { return cosine_hemisphere(u); }
float pdf_OrenNayar(vec3 wi, vec3 wo, float p[NP]) { return cosine_hemisphere_pdf(wi); }
