// Cook–Torrance with the Beckmann distribution.  p = [m, F0]
float brdf_CookTorrance(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    float woh = dot(wo, h);
    float g = min(1.0, min(2.0 * h.z * wo.z / woh, 2.0 * h.z * wi.z / woh));
    return beckmann_d(h, p[0], p[0]) * g * schlick(p[1], woh) / (4.0 * wi.z * wo.z);
}
vec3 sample_CookTorrance(vec3 wo, vec2 u, float p[NP]) { return reflect_about(wo, beckmann_half(p[0], p[0], u)); }
float pdf_CookTorrance(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    return half_pdf_from(beckmann_d(h, p[0], p[0]) * h.z, wi, wo);
}
