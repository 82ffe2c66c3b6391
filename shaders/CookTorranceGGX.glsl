// Cook–Torrance with the GGX distribution and separable Smith masking.  p = [m, F0]
float smith_ggx_g1(float c, float a) {
    float c2 = max(c * c, 1e-12);
    return 2.0 / (1.0 + sqrt(1.0 + a * a * (1.0 - c2) / c2));
}
float brdf_CookTorranceGGX(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    float g = smith_ggx_g1(wi.z, p[0]) * smith_ggx_g1(wo.z, p[0]);
    return ggx_d(h, p[0]) * g * schlick(p[1], dot(wo, h)) / (4.0 * wi.z * wo.z);
}
vec3 sample_CookTorranceGGX(vec3 wo, vec2 u, float p[NP]) { return reflect_about(wo, ggx_visible_half(wo, p[0], u)); }
float pdf_CookTorranceGGX(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    float cos_o = max(wo.z, TINY);
    return half_pdf_from(ggx_d(h, p[0]) * smith_ggx_g1(cos_o, p[0]) * max(dot(wo, h), 0.0) / cos_o, wi, wo);
}
